"""Analysis: repeated-measures statistics on tidy tables and the MNE ERP pipeline."""
