"""Analytic solutions and ready-made validation cases (numerics.md H)."""
