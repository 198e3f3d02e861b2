"""Graphs, training configs, glove profiles and calibrations, and models shipped with handflow.

Read through :mod:`importlib.resources` (docs/pipelines.md, "Shipped graphs").
"""
