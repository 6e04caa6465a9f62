"""The report: statistics, tables, figures and claims, built from the recorded data alone."""
