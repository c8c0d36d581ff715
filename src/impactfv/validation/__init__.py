"""Analytic solutions and ready-made validation cases (docs/validation.md)."""
