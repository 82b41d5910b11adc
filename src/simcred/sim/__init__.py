"""The simulator: batched vehicle models, experiments and seeded campaigns (serial or on Dask)."""
