"""jointid.signal."""
