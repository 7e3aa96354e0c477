"""Judging signals: the comparison rule (compare), run health (health),
energy and power balance (energy), and reading cost tables (cost_tables)."""
