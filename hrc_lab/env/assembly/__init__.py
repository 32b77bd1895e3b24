"""The assemble-to-order world of Ch.5 (thesis Sec. 5.3, Table 5.1): a worker assembles a product on a bracket.

- :mod:`~hrc_lab.env.assembly.spec`: the domain, pure Python: part types, goal configurations, scenarios (5.4.2),
  the expert's task structure, semantic plans and the action labels of Table 5.1 (``conf/env/ato*.yaml``);
- :mod:`~hrc_lab.env.assembly.video`: generated top-down videos of the assembly cell (OpenCV), a rendered right hand
  performing the 18 actions, single-action clips and whole sessions, the data of the Ch.5 perception experiments;
- :mod:`~hrc_lab.env.assembly.hand_drawing`: the right hand those videos draw, so that MediaPipe detects it.

This package imports nothing itself: the spec stays light, OpenCV is imported with the video modules.
"""
