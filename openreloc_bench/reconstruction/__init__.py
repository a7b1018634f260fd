"""Posed RGB-D frames and their 2D masks -> a fused scene point cloud and its 3D instances.

:mod:`.fusion` (TSDF) -> :mod:`.observation` (what each frame sees of the cloud) -> :mod:`.instances`
(masks to instances as a method configures it: :mod:`.lifting`'s voting and view-consensus clustering,
:mod:`.affinity_grouping` with :mod:`.plane_split`, :mod:`.instance_repair`). Geometry of the core:
OpenReLoc's map and the goreloc baseline are both built on it, and it imports neither.
"""
