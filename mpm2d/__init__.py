"""mpm2d tier (in progress)."""
