"""The files that leave lampfab: ``lens.stl`` (``stl``), ``lens.step`` (``step_file``,
with the lamp's solid in ``brep`` and the B-spline surfaces in ``bspline``) and
``lens.glb`` (``gltf``)."""
