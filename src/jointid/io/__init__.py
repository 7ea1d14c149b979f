"""jointid.io."""
