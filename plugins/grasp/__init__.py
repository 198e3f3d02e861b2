"""Grasp manifolds and experience-based grasping (docs/grasping.md, thesis chapter 4).

- :mod:`.pcp` — the partial-contact-posture distance and best-match search;
- :mod:`.som` — the SOM grasp manifold (:class:`~.som.SOM`);
- :mod:`.experience` — experience bases (SOM nodes, raw grasp database, manifold postures) and
  grasp datasets on disk;
- :mod:`.hand_layout` — fingers, segments and joints of a simulated hand, PCP masks from contacts;
- :mod:`.controller` — the experience-based grasp controller (phases A–D), a plain class;
- :mod:`.episode`, :mod:`.stability`, :mod:`.generation`, :mod:`.evaluation` — grasping in pybullet;
- :mod:`.training`, :mod:`.plots` — SOMs from grasp datasets, U-matrix and node-posture pictures;
- :mod:`.node`, :mod:`.cli` — the runtime node and the commands.
"""
