"""Hand and sensor tables shared by the glove, mapping, simulator and controller families.

- :mod:`.joints` — joint names, limits and groups of the human, ShadowHand-like and Gifu-like hands;
- :mod:`.sensors` — the CyberGlove II sensor table.

Plain data and small helpers; no runtime, no other family (docs/architecture.md).
"""
