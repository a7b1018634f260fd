"""Synthetic indoor scene generation (habitat-free): assets, layout, rendering, trajectories, variants.

Public entry points (import the submodules; this package does not import the renderer, so importing
``generators.assets`` never touches OpenGL):

- :func:`generators.spec.load_suite`, :class:`generators.spec.SceneSpec` — what to generate;
- :func:`generators.generate.generate_scene` / :func:`generators.generate.generate_suite` — write scenes;
- :func:`generators.layout.build_layout` and :func:`generators.render.create_renderer` — render a
  layout from any pose (used by the gymnasium environment).
"""
