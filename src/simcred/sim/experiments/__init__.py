"""Experiments of Neurohr et al. 2023 regenerated in simcred's simulator."""
