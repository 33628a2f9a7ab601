"""`python -m ipsph.sweeps`: print the summary.csv column table that docs/sweeps.md embeds."""

from .records import summary_columns_markdown

print(summary_columns_markdown(), end="")
