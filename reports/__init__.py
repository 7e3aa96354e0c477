"""Report rendering: HTML (with plots), CSV and Markdown from discrepancy
records. Generated output goes under reports/out/ (git-ignored)."""
