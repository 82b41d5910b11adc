"""Reproductions of the papers' experiments, with their qualitative claims checked."""
