"""jointid.identify."""
