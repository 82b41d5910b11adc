"""Contracts for simulation models (Braun et al., seed 003): assertions, algebra, configuration."""
