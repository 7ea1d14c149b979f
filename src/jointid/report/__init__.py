"""jointid.report: tables, figures and self-contained HTML; all plotting lives here."""
