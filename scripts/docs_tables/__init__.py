"""The book's results tables, written by scripts/docs-tables.py (its command line and the run
of the commands stay there): one module per command's tables (battery, plan, cvar), the
LightGBM and spec-sheet tables from committed JSON (lgbm, spec), the README's headline
figures (readme), and what they share (common)."""
