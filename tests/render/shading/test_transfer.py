"""Relighting transfer and gain (render.shading.transfer): against brute-force quadrature, the
identity, the energy clamp, the world's up."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading import transfer as rl
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
    """Points in a trench between two big spheres (about 40 % of their light blocked): the SSDF
    share brings the transfer within 15 % of the exact ray test (measured 3-5 % with 16 lobes;
    ignoring the occluders is 39-42 % off)."""
    env = _sky()
    lt = rl.relight_lighting(env, kernel="lambert", k=16)
    sp = SphereSet(np.array([[0.25, 0, 0.0], [-0.25, 0, 0.0]]), np.array([0.2, 0.2]))
    x = np.array([[0, y, 0.0] for y in np.linspace(-0.1, 0.1, 5)])
    src = env.resized(rl.TRANSFER_TABLE_H)
    for nrm in ([0, 0, 1.0], [0.3, 0, 1], [0, 0.5, 1]):
        n = np.tile(_unit(nrm), (5, 1))
        got = rl.transfer(x, n, lt, sp)
        ref = _brute(src, x, n, "lambert", sp)
        free = _brute(src, x, n, "lambert")
        err = np.abs(got - ref).sum(1) / free.sum(1)
        err_none = np.abs(free - ref).sum(1) / free.sum(1)
        assert err_none.mean() > 0.35 and err.mean() < 0.15 and err.mean() < 0.3 * err_none.mean(), (err, err_none)


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
    np.testing.assert_allclose(g, [1, 2, 1], rtol=0.05)  # the maps also hold a dim uniform floor
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
    """Orientations sweeping through the terminator of the capture's only (sharp) light: the gain
    stays finite, within the clamp, and changes smoothly (no spike where the capture transfer
    passes through ~0)."""
    a = rl.relight_lighting(_point_light([1.0, 0, 0], [1, 1, 1]), k=2)
    b = rl.relight_lighting(_point_light([0, 0, 1.0], [2, 2, 2]), k=2)
    g = rl.global_gain(a, b)
    ang = np.radians(np.arange(60.0, 120.01, 0.5))  # angle of n from the light at +x, in the x-z plane
    n = np.stack([np.cos(ang), np.zeros_like(ang), np.sin(ang)], -1)
    q = rl.relight_gain(np.zeros((len(n), 3)), n, a, b)[:, 0]
    assert np.all(np.isfinite(q)) and q.min() >= 0 and q.max() <= rl.MAX_GAIN * g[0] + 1e-12
    assert np.abs(np.diff(q)).max() < 0.25 * g[0], np.abs(np.diff(q)).max()
    assert q[-1] > q[0]  # away from A's light, B's light dominates


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


def test_henyey_greenstein_has_mean_one():
    c = (np.arange(100000) + 0.5) / 100000 * 2 - 1
    for g in (0.0, 0.5, 0.8, -0.3):
        assert rl.henyey_greenstein(c, g).mean() == pytest.approx(1.0, rel=1e-3)


def test_forward_scattering_lights_back_lit_fur():
    """One light behind the object as seen by the camera (v = -light) scatters forwards into the
    view more than the same light behind the camera (v = light); the gain of a map that moves the
    light to the back follows; views=None is the view-independent transfer."""
    lt = rl.relight_lighting(_point_light([1.0, 0, 0], [1, 1, 1]), kernel="wrap", k=2)
    n = np.array([[0, 0, 1.0]])
    back = rl.forward_transfer(lt, n, np.array([[-1.0, 0, 0]]))
    front = rl.forward_transfer(lt, n, np.array([[1.0, 0, 0]]))
    assert back[0, 0] > 5 * front[0, 0]
    t0 = rl.transfer(np.zeros((1, 3)), n, lt)
    np.testing.assert_allclose(rl.transfer(np.zeros((1, 3)), n, lt, views=np.array([[-1.0, 0, 0]]), forward=0.0), t0)


def test_mixed_kernel_is_the_weighted_sum_of_its_basis():
    """A ``mix:`` kernel's table, forward transfer and reference are the weighted sums of its basis
    kernels' (transfers are linear in the kernel), and malformed weights are refused."""
    env = _sky()
    w = [0.1, 0.2, 0.3, 0.4]
    lt = rl.relight_lighting(env, kernel=rl.mix_kernel(w), k=4)
    parts = [rl.relight_lighting(env, kernel=rl.mix_kernel(np.eye(4)[j]), fit=None, k=4) for j in range(4)]
    np.testing.assert_allclose(lt.table, sum(wj * p.table for wj, p in zip(w, parts)), rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(lt.reference, sum(wj * p.reference for wj, p in zip(w, parts)), rtol=1e-6)
    n, v = fibonacci_directions(32), _unit(np.roll(fibonacci_directions(32), 5, axis=0))
    np.testing.assert_allclose(rl.forward_transfer(lt, n, v),
                               sum(wj * rl.forward_transfer(p, n, v) for wj, p in zip(w, parts)), rtol=1e-9)
    # the uniform basis kernel: the same transfer at every orientation (4 pi x the mean radiance)
    uni = parts[3].table.reshape(-1, 3)
    np.testing.assert_allclose(uni, np.broadcast_to(4 * np.pi * parts[3].mean, uni.shape), rtol=2e-3)
    for bad in ([0, 0, 0, 0], [1, -1, 0, 0], [1, 1, 1]):
        with pytest.raises(ValueError, match="mix kernel"):
            rl.mix_kernel(bad)
    with pytest.raises(ValueError, match="kernel"):
        rl.kernel_fn("mix:1,x,0,0")
