"""jointid.rig."""
