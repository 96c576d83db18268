"""Numerical building blocks shared by the engine and the analysis (numpy only)."""
