"""Scripted demonstrations (cap turning, ball swapping) recorded from the simulator, and their loaders."""

from .loaders import load_ball_demonstrations, load_cap_demonstrations

__all__ = ["load_ball_demonstrations", "load_cap_demonstrations"]
