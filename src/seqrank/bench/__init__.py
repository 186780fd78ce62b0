"""`seqrank bench`: the reference and fast training paths timed side by side."""
