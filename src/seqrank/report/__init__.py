"""`seqrank report`: tables, statistics and plots over run directories."""
