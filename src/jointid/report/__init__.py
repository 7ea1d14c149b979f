"""jointid.report."""
