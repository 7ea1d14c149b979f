"""jointid.simulate."""
