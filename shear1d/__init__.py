"""shear1d tier (in progress)."""
