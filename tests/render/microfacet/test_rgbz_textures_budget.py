"""Full-frame texture layers past their budget fail with a clear error before any GL memory is taken."""

from __future__ import annotations

import pytest

from render.microfacet import rgbz_textures as rt


class _Views:
    """What layer_textures reads of an RgbzImages before it allocates: count, size, matte."""

    def __init__(self, n, size, has_alpha=True):
        self.n, self.size, self.has_alpha = n, size, has_alpha

    def __len__(self):
        return self.n


def test_phone_sized_model_is_refused_with_the_way_out():
    with pytest.raises(ValueError, match=r"200 views need 5\.1 GiB .*--method gather"):
        rt.layer_textures(None, _Views(200, (1920, 1440)))


def test_within_budget_reaches_the_allocation():
    class Ctx:
        def texture_array(self, *a, **k):
            raise RuntimeError("allocating")

    with pytest.raises(RuntimeError, match="allocating"):
        rt.layer_textures(Ctx(), _Views(72, (1280, 960)))
