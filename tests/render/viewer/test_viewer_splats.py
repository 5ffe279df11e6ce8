"""``furrow view``'s "splats in the browser" toggle (render.viewer.server.Viewer.client_splats) with a
recording stand-in for the viser client: the client gets viser's splat node of the model's
Gaussians (positions back in metres through the node scale), its render thread pauses and its
server picture is cleared; unticked, the node goes and the thread resumes."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from render.viewer.server import CLIENT_SPLATS_NODE, Viewer
from tests import scenes as sc
from volume.splats import build_splats


class Node:
    def __init__(self):
        self.removed = False

    def remove(self):
        self.removed = True


class Scene:
    def __init__(self):
        self.calls = []

    def add_gaussian_splats(self, name, **kw):
        self.calls.append(("splats", name, kw))
        return Node()

    def set_background_image(self, image, *a, **kw):
        self.calls.append(("background", image))


def test_client_splats_toggle():
    model = sc.build_model(sc.ring_cameras(6, 48, 36))
    splats = build_splats(model)
    viewer = SimpleNamespace(splats=lambda: splats, _client_nodes={})
    client = SimpleNamespace(client_id=7, scene=Scene())
    paused, notes = [], []
    session = SimpleNamespace(pause=paused.append)
    box = SimpleNamespace(value=True)
    Viewer.client_splats(viewer, client, session, box, notes.append)
    kind, name, kw = client.scene.calls[0]
    assert kind == "splats" and name == CLIENT_SPLATS_NODE
    np.testing.assert_allclose(kw["centers"] * kw["scale"], splats.positions, rtol=1e-5, atol=1e-7)
    assert kw["covariances"].shape == (len(splats), 3, 3) and kw["opacities"].shape == (len(splats), 1)
    assert ("background", None) in client.scene.calls and paused == [True]
    assert any(f"{len(splats)} splats" in n for n in notes)
    node = viewer._client_nodes[7]
    box.value = False
    Viewer.client_splats(viewer, client, session, box, notes.append)
    assert node.removed and paused == [True, False] and 7 not in viewer._client_nodes
