"""jointid.modal."""
