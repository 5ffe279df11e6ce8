"""The compositing pass that follows any method's frame (docs/methods.md §3-§4).

- ``pipeline.py``: :func:`render.composite.pipeline.composite_frame`, the whole pass (background from the
  environment map, the object's ground shadow, the object, glare, tone mapping);
- ``gl.py``: the GL owner of the compositing shaders (:class:`render.composite.gl.Compositor`);
  ``reference.py``: their numpy twin;
- ``ground_shadow.py``: the ground plane and the shadow ratio from the sphere set (numpy reference);
- ``glare_layer.py``: the GL glare layer (streaks as additive fans; numpy maths in ``render.shading.glare``);
- ``tonemap.py``: HDR -> display; ``video.py``: the one MP4 writer;
- ``background.py``: what ``furrow render`` writes from a frame's soft alpha: RGBA PNG (straight
  alpha) or the frame flattened over ``--background COLOUR|MAP`` (premult + (1 - alpha) B, linear);
- ``shaders/``: ``composite_*.glsl``, ``glare_*.glsl``.
"""
