"""GOReloc (graph-based object-level relocalisation, RA-L 2024) re-implemented in Python.

Modules, one step each: :mod:`.vocabulary` (the closed COCO vocabulary and the generator table),
:mod:`.ellipsoid` (dual quadrics, projection, NGWD), :mod:`.detect` (labelled masks and the detection
filter), :mod:`.graph` (object graphs and descriptors), :mod:`.build` (the map from RGB-D frames),
:mod:`.map` (its file), :mod:`.localize` (RANSAC, P3P, refinement) and :mod:`.method` (the
``goreloc`` relocalizer).
"""
