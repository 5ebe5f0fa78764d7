"""Contact statics converges at any penalty stiffness, towards the rigid limit.

Four scenes (tests/stiff_contact_scenes.py: a heavy cantilever lying on a floor, a
rod laid over a sphere, two crossing rods, a ball resting in a sagging tube) start out of contact and are solved with
the default settings at stiffnesses 1e4 .. 1e10 (per length on the rods' obstacle
contacts, per point between the rods). The solve starts at a softer law where the
load would otherwise meet a contact far stiffer than what carries it, and raises the
stiffness tenfold per stage to the user's (``solve_statics``' stiffness
continuation). Truths checked:

- every solve succeeds within the default step budget;
- the deepest penetration falls as the stiffness rises, as ``f / k + delta / 2``
  does for the smoothed penalty (``delta`` = 1e-8 m);
- the centre line converges to the rigid-contact limit: its change over the two
  decades 1e8 -> 1e10 is at most a tenth of its change over 1e6 -> 1e8 (a penalty
  solution's distance from the rigid one goes as 1/k: a hundredth expected; the
  smoothing's delta / 2 offset and Newton's tolerance leave less);
- the contact carries the load: the floor holds most of the cantilever's weight.

The barrier law (its reach and force scale continued) converges at reaches 1e-3 ..
1e-6 m on the sphere and the floor, its gap a fraction of the reach, its centre line
converging to the penalty's rigid limit.
"""

import jax.numpy as jnp
import numpy as np
import pytest
from stiff_contact_scenes import BALL_MASS, SCENES, barrier_law, centre_line

import sorojax as sj

STIFFNESSES = (1e4, 1e6, 1e8, 1e10)


# the sphere in the default run; the floor's 8 divisions, the rod pair and the tube
# (compiles of 20, 30 and 10 s on 2 cores) in the slow one
PARAMS = [
    pytest.param(name, marks=() if name == "rod_over_sphere" else pytest.mark.slow)
    for name in sorted(SCENES)
]


@pytest.fixture(scope="module", params=PARAMS)
def solved(request):
    build = SCENES[request.param]
    out = {}
    for k in STIFFNESSES:
        lk = build(jnp.asarray(k))
        sol = sj.solve_statics(lk, throw=False, warn_unstable=False)
        out[k] = (lk, sol)
    return request.param, out


def test_converges_at_every_stiffness(solved):
    name, out = solved
    for k, (_, sol) in out.items():
        assert sol.result == sj.RESULTS.successful, (name, k, sol.result)
        assert int(sol.num_steps) < 64 * 20, (name, k, int(sol.num_steps))
        assert float(sol.residual_norm) < 1e-6, (name, k)


def test_penetration_falls_with_stiffness(solved):
    name, out = solved
    deepest = [float(jnp.max(out[k][1].contact.penetration)) for k in STIFFNESSES]
    assert all(d > 0 for d in deepest), (name, deepest)  # in contact at every k
    for soft, stiff in zip(deepest, deepest[1:], strict=False):
        assert stiff < 0.2 * soft, (name, deepest)
    # at 1e10 the penetration is the smoothing's delta / 2 plus f / k: nanometres
    assert deepest[-1] < 1e-7, (name, deepest)


def test_centre_line_converges_to_the_rigid_limit(solved):
    name, out = solved
    c = {k: centre_line(lk, sol.q) for k, (lk, sol) in out.items()}
    first = np.max(np.abs(c[1e8] - c[1e6]))
    second = np.max(np.abs(c[1e10] - c[1e8]))
    assert first > 0
    assert second < 0.1 * first, (name, first, second)


def test_contact_carries_the_load(solved):
    name, out = solved
    lk, sol = out[1e10]
    weight = 1000.0 * np.pi * 0.01**2 * 9.81  # N per metre of rod
    fz = np.asarray(sol.contact.total_force())[2]
    if name == "ball_in_tube":  # the bore carries the whole ball
        force = float(np.sum(np.asarray(sol.contact.force)[:, 2]))
        np.testing.assert_allclose(abs(force), BALL_MASS * 9.81, rtol=1e-6)
    elif name == "crossing_rods":  # action and reaction: the pair's forces cancel
        assert abs(fz) < 1e-9 * weight
        # the lower rod holds the upper one up (forces on the upper, link A), by
        # a share of its weight: the clamp holds the rest
        up = float(np.sum(np.asarray(sol.contact.force)[:, 2]))
        assert 0.3 * weight < up < 2.0 * weight, up
    else:  # the floor or sphere holds part of the weight; the clamp the rest
        assert 0.3 * weight < fz < weight, fz


# ------------------------------------------------------------------ the barrier
REACHES = (1e-3, 1e-4, 1e-5, 1e-6)


@pytest.fixture(scope="module", params=[
    "rod_over_sphere", pytest.param("cantilever_on_floor", marks=pytest.mark.slow)
])  # fmt: skip
def barrier_solved(request):
    """The scene on a barrier of each reach whose force scale k g_hat is the rod's
    weight per length (the guide's advice: at or below the load), and on the
    penalty at 1e10 (the rigid limit's neighbour)."""
    build = SCENES[request.param]
    out = {}
    for reach in REACHES:
        lk = build(None, law=barrier_law(reach))
        out[reach] = (lk, sj.solve_statics(lk, throw=False, warn_unstable=False))
    lk = build(jnp.asarray(1e10))
    out["penalty"] = (lk, sj.solve_statics(lk, throw=False, warn_unstable=False))
    return request.param, out


def test_barrier_converges_at_small_reaches(barrier_solved):
    """Reaches 1e-3 .. 1e-6 m (1e-1 .. 1e-4 of the radius) converge with the default
    settings (the solve starts at a reach of 5 % of the radius and narrows it
    tenfold per stage); the rod never touches and its smallest gap lies inside the
    reach and above the barrier's logarithmic floor (1e-2 of the reach, where the
    law turns linear): 0.11-0.31 of the reach on the floor, 0.012-0.014 over the
    sphere, whose contact carries several weights per length."""
    name, out = barrier_solved
    for reach in REACHES:
        _, sol = out[reach]
        assert sol.result == sj.RESULTS.successful, (name, reach, sol.result)
        gap = -float(jnp.max(sol.contact.penetration))
        assert 0.01 * reach < gap < reach, (name, reach, gap)


def test_barrier_converges_to_the_rigid_limit(barrier_solved):
    """The centre line's change per decade of the reach falls (the body stands off
    by a fraction of the reach: about tenfold per decade once the shape has
    settled; measured 1e-3, 3e-4, 5e-5 m over the sphere, 5e-4, 5e-5, 5e-6 m on the
    floor), and at 1e-6 m it lies within 1e-5 m of the penalty's at 1e10 N/m^2
    (which sinks by nanometres)."""
    name, out = barrier_solved
    c = {key: centre_line(lk, sol.q) for key, (lk, sol) in out.items()}
    pairs = zip(REACHES, REACHES[1:], strict=False)
    steps = [np.max(np.abs(c[b] - c[a])) for a, b in pairs]
    assert steps[0] > 0
    for coarse, fine in zip(steps, steps[1:], strict=False):
        assert fine < 0.5 * coarse, (name, steps)
    assert steps[-1] < 0.1 * steps[0], (name, steps)
    assert np.max(np.abs(c[1e-6] - c["penalty"])) < 1e-5, name
