"""Figures drawn from analysis result objects (matplotlib, Agg backend)."""
