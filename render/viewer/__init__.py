"""``furrow view``: an interactive web viewer (viser) that renders the model on the server.

* :mod:`render.viewer.adaptive`: pure functions that pick the frame size while the camera moves
  (frame budget from measured times) and what to render next (moving frame, full frame, wait);
* :mod:`render.viewer.gl_worker`: the one thread that owns the GL context and the renderers;
* :mod:`render.viewer.session`: one render thread per connected browser;
* :mod:`render.viewer.views`: the debug views and the environment compositing of a frame;
* :mod:`render.viewer.gui`: the viser controls; :mod:`render.viewer.server`: the whole server.
"""
