"""rheometer tier (in progress)."""
