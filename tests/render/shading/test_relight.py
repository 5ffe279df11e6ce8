"""Relighting transfer and gain (render.shading.relight): against brute-force quadrature, the
identity, the energy clamp, the world's up."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading import relight as rl
from render.shading.envmap import EnvMap, procedural_sky
from render.shading.ssdf import fibonacci_directions
from volume.model import SphereSet


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _sky():
    return procedural_sky(32)


def _brute(env: EnvMap, points, normals, kernel, spheres=None):
    """sum over the map's pixels of K(n.w) L(w) Omega(w) V(x, w), V by exact ray-sphere tests."""
    d = env.pixel_directions().reshape(-1, 3)
    lw = env.data.reshape(-1, 3).astype(np.float64) * env.pixel_solid_angles().reshape(-1, 1)
    out = []
    for x, n in zip(points, normals):
        w = rl.KERNELS[kernel](d @ n)
        if spheres is not None:
            for c, r in zip(spheres.centers, spheres.radii):
                oc = c - x
                t = d @ oc
                w = w * ~((t > 0) & (np.sum(oc * oc) - t * t < r * r))
        out.append(w @ lw)
    return np.array(out)


@pytest.mark.parametrize("kernel, value", [("lambert", np.pi), ("fur", np.pi ** 2)])
def test_kernel_integrals(kernel, value):
    assert rl.kernel_integral(kernel) == pytest.approx(value, rel=1e-6)


@pytest.mark.parametrize("kernel", ["lambert", "fur"])
def test_unoccluded_transfer_against_brute_force(kernel):
    """The table lookup is the exact kernel integral of the map to 2 % of the largest value (the
    table's interpolation; the sun of the procedural sky is its hardest case)."""
    env = _sky()
    lt = rl.relight_lighting(env, kernel=kernel, k=4)
    n = fibonacci_directions(64)
    got = rl.unoccluded_transfer(lt, n)
    ref = _brute(env.resized(rl.TRANSFER_TABLE_H), np.zeros((64, 3)), n, kernel)
    assert np.max(np.abs(got - ref)) < 0.02 * ref.max()


def test_sphere_occlusion_against_ray_tests():
    """A sphere beside the point takes light away as the exact ray test says, to the accuracy of the
    SSDF model: within 15 % of the unoccluded transfer."""
    env = _sky()
    lt = rl.relight_lighting(env, k=8)
    sun = _unit(rl.world_to_env((0, 0, 1.0)).T @ np.array([0.64, 0.54, 0.57]))
    sp = SphereSet(np.array([0.35 * sun + [0, 0, 0.02]]), np.array([0.15]))
    x = np.zeros((3, 3))
    n = _unit([[0, 0, 1.0], sun, [1.0, 0.0, 0.2]])
    got = rl.transfer(x, n, lt, sp)
    src = env.resized(rl.TRANSFER_TABLE_H)
    ref = _brute(src, x, n, "lambert", sp)
    free = _brute(src, x, n, "lambert")
    assert np.all(ref.sum(1)[:2] < 0.8 * free.sum(1)[:2])  # the sun is blocked at the first two
    assert np.max(np.abs(got - ref).sum(1) / free.sum(1)) < 0.15


def test_same_lighting_is_the_identity():
    lt = rl.relight_lighting(_sky(), k=4)
    sp = SphereSet(np.array([[0.0, 0.0, -0.5]]), np.array([0.4]))
    x = np.random.default_rng(5).normal(size=(50, 3)) * 0.1
    n = np.random.default_rng(6).normal(size=(50, 3))
    np.testing.assert_allclose(rl.relight_gain(x, n, lt, lt, sp), 1.0, rtol=1e-12)


def _point_light(direction, colour, h=32):
    d = EnvMap(np.zeros((h, 2 * h, 3), np.float32)).pixel_directions()
    lobe = np.exp(400.0 * (d @ _unit(direction) - 1))[..., None] * np.asarray(colour, np.float64)
    return EnvMap((lobe + 1e-4).astype(np.float32), "light")


def test_energy_clamp_where_the_capture_saw_nothing():
    """A point the capture barely lit gets at most MAX_GAIN x the global gain, never inf / NaN;
    what only the capture lit goes dark; a zero gradient takes the global gain; the regulariser
    alone keeps the quotient finite."""
    a = rl.relight_lighting(_point_light([0, 0, 1.0], [1, 1, 1]), k=2)
    b = rl.relight_lighting(_point_light([0, 0, -1.0], [1, 2, 1]), k=2)
    g = rl.global_gain(a, b)
    np.testing.assert_allclose(g, [1, 2, 1], rtol=1e-3)
    n = np.array([[0, 0, -1.0], [0, 0, 1.0], [0, 0, 0]])  # lit by B only, by A only, no orientation
    q = rl.relight_gain(np.zeros((3, 3)), n, a, b)
    assert np.all(np.isfinite(q)) and np.all(q >= 0)
    np.testing.assert_allclose(q[0], rl.MAX_GAIN * g)  # about 1 / REGULARISE = 20 x without the clamp
    assert np.all(q[1] < 0.1 * g)
    np.testing.assert_allclose(q[2], g)
    q0 = rl.gain_from_transfers(np.zeros((1, 3)), np.full((1, 3), 1e-3), np.ones(3), np.ones(3), g, [True],
                                max_gain=np.inf)
    np.testing.assert_allclose(q0[0], (1e-3 + rl.REGULARISE) / rl.REGULARISE)


def test_grazing_orientation_stays_bounded():
    """Orientations the light grazes (n perpendicular to the only light in A and in B): bounded
    by the clamp, finite, and equal to the global gain when both lights are symmetric about n."""
    a = rl.relight_lighting(_point_light([1.0, 0, 0], [1, 1, 1]), k=2)
    b = rl.relight_lighting(_point_light([-1.0, 0, 0], [2, 2, 2]), k=2)
    q = rl.relight_gain(np.zeros((2, 3)), np.array([[0, 0, 1.0], [0, 1.0, 0]]), a, b)
    np.testing.assert_allclose(q, 2.0, rtol=0.02)


def test_lighting_follows_the_world_up():
    """The world's up becomes the map's +z: a map lit from its +z, for a world whose up is -y,
    lights world normals pointing to -y."""
    lt = rl.relight_lighting(_point_light([0, 0, 1.0], [1, 1, 1]), up=(0.0, -1.0, 0.0), k=2)
    t = rl.transfer(np.zeros((2, 3)), np.array([[0, -1.0, 0], [0, 1.0, 0]]), lt)
    assert t[0, 0] > 20 * t[1, 0]
    np.testing.assert_allclose(lt.axes[np.argmax(lt.mus[:, 0])], [0, -1, 0], atol=0.05)


def test_gain_bounded_on_a_real_map():
    a = rl.relight_lighting(_sky(), kernel="fur", k=4)
    b = rl.relight_lighting(_sky().rotated(np.pi), kernel="fur", k=4)
    n = np.concatenate([fibonacci_directions(200), np.zeros((1, 3))])
    q = rl.relight_gain(np.zeros((201, 3)), n, a, b)
    assert np.all(np.isfinite(q)) and q.min() >= 0 and q.max() <= rl.MAX_GAIN * rl.global_gain(a, b).max() + 1e-12
