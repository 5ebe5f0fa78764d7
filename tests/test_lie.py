"""Tests for :mod:`sorojax.lie` (SO(3)/SE(3) maps, adjoints, tangent operators).

All tests run in float64. Reference values come from ``jax.scipy.linalg.expm``,
matrix identities, truncated power series (which are polynomials, hence have
exact derivatives of every order) and central finite differences.
"""

import functools

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from sorojax import lie  # noqa: E402

PI = np.pi
SERIES_TERMS = 30


# ---------------------------------------------------------------------------
# Sample inputs
# ---------------------------------------------------------------------------


def _twists_with_angles(key, angles):
    """Twists whose angular part has the given norms (random axes, v ~ N(0, 1))."""
    angles = jnp.asarray(angles, dtype=jnp.float64)
    k1, k2 = jax.random.split(key)
    axes = jax.random.normal(k1, (angles.shape[0], 3), dtype=jnp.float64)
    axes = axes / jnp.linalg.norm(axes, axis=1, keepdims=True)
    v = jax.random.normal(k2, (angles.shape[0], 3), dtype=jnp.float64)
    return jnp.concatenate([axes * angles[:, None], v], axis=1)


def _random_twists(seed, n=4, max_angle=3.0):
    k1, k2 = jax.random.split(jax.random.PRNGKey(seed))
    angles = jax.random.uniform(k1, (n,), dtype=jnp.float64, maxval=max_angle)
    return _twists_with_angles(k2, angles)


def _tiny_twists(seed, n=2, scale=1e-7):
    key = jax.random.PRNGKey(seed)
    return scale * jax.random.normal(key, (n, 6), dtype=jnp.float64)


ZERO = jnp.zeros((1, 6), dtype=jnp.float64)
RANDOM = _random_twists(0)
TINY = _tiny_twists(1)
NEAR_PI = _twists_with_angles(jax.random.PRNGKey(2), [PI - 1e-6, PI - 1e-9])
AT_PI = _twists_with_angles(jax.random.PRNGKey(3), [PI, PI])
# Angles right at the branch switches: theta^2 = get_epsilon (Taylor/closed form
# of the coefficient functions) and theta = pi/2 (log_so3 axis extraction).
_EPS64 = lie.get_epsilon(jnp.float64)
SWITCH = _twists_with_angles(
    jax.random.PRNGKey(4),
    [
        np.sqrt(_EPS64) * (1 - 1e-12),
        np.sqrt(_EPS64) * (1 + 1e-12),
        PI / 2 - 1e-9,
        PI / 2 + 1e-9,
    ],
)
BELOW_PI = jnp.concatenate([ZERO, TINY, RANDOM, NEAR_PI, SWITCH])
ALL = jnp.concatenate([BELOW_PI, AT_PI])


# ---------------------------------------------------------------------------
# Reference implementations
# ---------------------------------------------------------------------------


def _np_hat3(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def _np_hat(x):
    out = np.zeros((4, 4), dtype=x.dtype)
    out[:3, :3] = _np_hat3(x[:3])
    out[:3, 3] = x[3:]
    return out


def _np_ad(x):
    out = np.zeros((6, 6), dtype=x.dtype)
    out[:3, :3] = out[3:, 3:] = _np_hat3(x[:3])
    out[3:, :3] = _np_hat3(x[3:])
    return out


def _np_exp_series(x, terms=SERIES_TERMS):
    """NumPy sum_{k<=terms} hat(x)^k / k! (a polynomial, complex-safe)."""
    X = _np_hat(x)
    out = power = np.eye(4, dtype=x.dtype)
    for k in range(1, terms + 1):
        power = power @ X / k
        out = out + power
    return out


def _np_dexp_series(x, terms=SERIES_TERMS):
    """NumPy sum_{k<=terms} ad(x)^k / (k+1)! (a polynomial, complex-safe)."""
    A = _np_ad(x)
    out = power = np.eye(6, dtype=x.dtype)
    for k in range(1, terms + 1):
        power = power @ A / (k + 1)
        out = out + power
    return out


def _np_hessian(f, x, h=1e-30, delta=1e-5):
    """Hessian of a real-analytic scalar f: complex step in i, central FD in j.

    H_ij = [Im f(x + i h e_i + delta e_j) - Im f(x + i h e_i - delta e_j)]
           / (2 h delta), accurate to O(h^2 + delta^2) + O(ulp / delta).
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    hess = np.empty((n, n))
    eye = np.eye(n)
    for i in range(n):
        for j in range(n):
            xp = x + 1j * h * eye[i] + delta * eye[j]
            xm = x + 1j * h * eye[i] - delta * eye[j]
            hess[i, j] = (f(xp).imag - f(xm).imag) / (2 * h * delta)
    return hess


@functools.cache
def _batched(f):
    """jit(vmap(f)), cached per function so that shared functions compile once."""
    return jax.jit(jax.vmap(f))


def _central_jacobian(f, x, h=1e-6):
    """Central finite-difference Jacobian of f at x, shape f(x).shape + x.shape."""
    x = jnp.asarray(x)
    flat = x.reshape(-1)
    basis = jnp.eye(flat.size, dtype=x.dtype)

    def column(e):
        xp = (flat + h * e).reshape(x.shape)
        xm = (flat - h * e).reshape(x.shape)
        return (f(xp) - f(xm)) / (2 * h)

    cols = jax.vmap(column)(basis)  # (n_in, *out)
    return jnp.moveaxis(cols, 0, -1).reshape(f(x).shape + x.shape)


def _max_err(a, b):
    return float(jnp.max(jnp.abs(a - b)))


# ---------------------------------------------------------------------------
# 1. Exponential maps vs expm
# ---------------------------------------------------------------------------


def test_exp_so3_matches_expm():
    ws = ALL[:, :3]
    ours = _batched(lie.exp_so3)(ws)
    ref = _batched(lambda w: jax.scipy.linalg.expm(lie.hat3(w)))(ws)
    # Both are accurate to a few ulps for angles <= pi.
    err = _max_err(ours, ref)
    assert err < 1e-12, f"exp_so3 differs from expm(hat3(w)) by {err:.3e}"


def test_exp_se3_matches_expm():
    ours = _batched(lie.exp_se3)(ALL)
    ref = _batched(lambda x: jax.scipy.linalg.expm(lie.hat(x)))(ALL)
    # Both are accurate to a few ulps for angles <= pi and |v| ~ 1.
    err = _max_err(ours, ref)
    assert err < 1e-12, f"exp_se3 differs from expm(hat(xi)) by {err:.3e}"


def test_exp_so3_is_rotation_at_pi():
    R = _batched(lie.exp_so3)(AT_PI[:, :3])
    err = _max_err(jnp.einsum("nij,nkj->nik", R, R), jnp.eye(3)[None])
    # Orthogonality holds to roundoff.
    assert err < 1e-14, f"exp_so3 at angle pi is not orthogonal: R R^T - I = {err:.3e}"


# ---------------------------------------------------------------------------
# 2. Logarithm
# ---------------------------------------------------------------------------


def test_log_exp_roundtrip_below_pi():
    xs = jnp.concatenate([ZERO, TINY, RANDOM, SWITCH])
    back = _batched(lambda x: lie.log_se3(lie.exp_se3(x)))(xs)
    # log is well conditioned away from pi: error is a few ulps times |xi|.
    err = _max_err(back, xs)
    assert err < 1e-10, f"log_se3(exp_se3(xi)) - xi = {err:.3e}"


def test_log_exp_roundtrip_near_pi():
    back = _batched(lambda x: lie.log_se3(lie.exp_se3(x)))(NEAR_PI)
    # Near pi the angle is recovered from atan2(sin, cos) with absolute accuracy
    # ~ulp; the axis comes from the symmetric part, so the error stays at roundoff
    # level, we still allow 1e-9 for the reduced conditioning there.
    err = _max_err(back, NEAR_PI)
    assert err < 1e-9, f"log_se3(exp_se3(xi)) - xi near pi = {err:.3e}"


def test_exp_log_roundtrip():
    gs = _batched(lie.exp_se3)(ALL)
    back = _batched(lambda g: lie.exp_se3(lie.log_se3(g)))(gs)
    # exp(log(g)) reproduces g to roundoff, including at and near angle pi.
    err = _max_err(back, gs)
    assert err < 1e-12, f"exp_se3(log_se3(g)) - g = {err:.3e}"


def test_log_so3_at_pi_has_angle_pi():
    Rs = _batched(lie.exp_so3)(AT_PI[:, :3])
    ws = _batched(lie.log_so3)(Rs)
    err = _max_err(jnp.linalg.norm(ws, axis=1), PI)
    # The angle at pi comes from atan2(~0, -1): exact to roundoff.
    assert err < 1e-12, f"|log_so3(R)| - pi at angle pi = {err:.3e}"
    par = jnp.abs(jnp.sum(ws * AT_PI[:, :3], axis=1)) / PI**2
    # The axis may flip sign at exactly pi, but must be parallel to the input axis.
    assert _max_err(par, 1.0) < 1e-12, "log_so3 axis at angle pi is not parallel"


def test_log_se3_of_identity_is_zero():
    out = jax.jit(lie.log_se3)(jnp.eye(4))
    assert jnp.all(out == 0.0), f"log_se3(I) = {out}"


# ---------------------------------------------------------------------------
# 3. Group adjoints
# ---------------------------------------------------------------------------


def test_Ad_matches_conjugation():
    gs = _batched(lie.exp_se3)(ALL)
    ys = _random_twists(10, n=ALL.shape[0])
    ours = _batched(lambda g, y: lie.Ad(g) @ y)(gs, ys)
    ref = _batched(lambda g, y: lie.vee(g @ lie.hat(y) @ lie.inverse_se3(g)))(gs, ys)
    # Pure products of O(1) matrices: roundoff only.
    err = _max_err(ours, ref)
    assert err < 1e-12, f"Ad(g) y - vee(g hat(y) g^-1) = {err:.3e}"


def test_Ad_inv_is_inverse_of_Ad():
    gs = _batched(lie.exp_se3)(ALL)
    ours = _batched(lie.Ad_inv)(gs)
    ref = _batched(lambda g: jnp.linalg.inv(lie.Ad(g)))(gs)
    ref2 = _batched(lambda g: lie.Ad(lie.inverse_se3(g)))(gs)
    # Ad is orthogonal-like and well conditioned for |p| ~ 1: roundoff only.
    assert _max_err(ours, ref) < 1e-12, "Ad_inv(g) differs from inv(Ad(g))"
    assert _max_err(ours, ref2) < 1e-12, "Ad_inv(g) differs from Ad(inverse_se3(g))"


def test_inverse_se3_is_matrix_inverse():
    gs = _batched(lie.exp_se3)(ALL)
    prod = _batched(lambda g: g @ lie.inverse_se3(g))(gs)
    # Roundoff only.
    err = _max_err(prod, jnp.eye(4)[None])
    assert err < 1e-13, f"g @ inverse_se3(g) - I = {err:.3e}"


def test_Ad_is_homomorphism():
    g1 = _batched(lie.exp_se3)(RANDOM)
    g2 = _batched(lie.exp_se3)(_random_twists(11, n=RANDOM.shape[0]))
    lhs = _batched(lambda a, b: lie.Ad(a @ b))(g1, g2)
    rhs = _batched(lambda a, b: lie.Ad(a) @ lie.Ad(b))(g1, g2)
    # Roundoff only.
    err = _max_err(lhs, rhs)
    assert err < 1e-12, f"Ad(g1 g2) - Ad(g1) Ad(g2) = {err:.3e}"


def test_hat_vee_make_se3_roundtrips():
    @jax.jit
    def roundtrips(x):
        g = lie.exp_se3(x)
        return (
            lie.vee(lie.hat(x)),
            lie.vee3(lie.hat3(x[:3])),
            g,
            lie.make_se3(g[:3, :3], g[:3, 3]),
        )

    x = RANDOM[0]
    xv, wv, g, g2 = roundtrips(x)
    # Pure data movement: exact.
    assert jnp.all(xv == x), "vee(hat(x)) != x"
    assert jnp.all(wv == x[:3]), "vee3(hat3(w)) != w"
    assert jnp.all(g2 == g), "make_se3(R, p) != g"


# ---------------------------------------------------------------------------
# 4. Algebra adjoints
# ---------------------------------------------------------------------------


def test_ad_matches_bracket():
    xs = RANDOM
    ys = _random_twists(12, n=xs.shape[0])
    ours = _batched(lambda x, y: lie.ad(x) @ y)(xs, ys)
    ref = _batched(
        lambda x, y: lie.vee(lie.hat(x) @ lie.hat(y) - lie.hat(y) @ lie.hat(x))
    )(xs, ys)
    # Roundoff only.
    err = _max_err(ours, ref)
    assert err < 1e-12, f"ad(x) y - vee([hat(x), hat(y)]) = {err:.3e}"


def test_coad_is_minus_ad_transpose():
    ours = _batched(lie.coad)(RANDOM)
    ref = _batched(lambda x: -lie.ad(x).T)(RANDOM)
    # Same entries up to sign: exact.
    assert _max_err(ours, ref) == 0.0, "coad(x) != -ad(x).T"


# ---------------------------------------------------------------------------
# 5. Tangent operators
# ---------------------------------------------------------------------------


def _dexp_fd_residual(x, d, h=1e-6):
    plus = lie.exp_se3(x + h * d)
    minus = lie.exp_se3(x - h * d)
    lhs = (plus - minus) / (2 * h) @ lie.inverse_se3(lie.exp_se3(x))
    return lhs - lie.hat(lie.dexp_se3(x) @ d)


def test_dexp_se3_matches_finite_differences():
    ds = _random_twists(13, n=ALL.shape[0])
    res = _batched(_dexp_fd_residual)(ALL, ds)
    # Central differences with h=1e-6: O(h^2) ~ 1e-12 truncation plus
    # O(ulp / h) ~ 1e-10 roundoff.
    err = float(jnp.max(jnp.abs(res)))
    assert err < 1e-8, f"dexp_se3 vs finite differences of exp_se3: {err:.3e}"


def test_dexp_so3_matches_finite_differences():
    ws = ALL[:, :3]
    ds = _random_twists(14, n=ws.shape[0])[:, :3]
    h = 1e-6

    def residual(w, d):
        fd = (lie.exp_so3(w + h * d) - lie.exp_so3(w - h * d)) / (2 * h)
        return fd @ lie.exp_so3(w).T - lie.hat3(lie.dexp_so3(w) @ d)

    # Central differences, same error budget as for SE(3).
    err = float(jnp.max(jnp.abs(_batched(residual)(ws, ds))))
    assert err < 1e-8, f"dexp_so3 vs finite differences of exp_so3: {err:.3e}"


def test_dexp_se3_matches_series():
    xs = jnp.concatenate([ZERO, TINY, _random_twists(15, max_angle=2.0), SWITCH])
    ours = _batched(lie.dexp_se3)(xs)
    ref = np.stack([_np_dexp_series(np.asarray(x)) for x in xs])
    # For |ad| <~ 3 the 30-term series has converged to roundoff.
    err = _max_err(ours, ref)
    assert err < 1e-12, f"dexp_se3 vs truncated series: {err:.3e}"


def test_dexp_se3_inv_is_inverse():
    prod = _batched(lambda x: lie.dexp_se3_inv(x) @ lie.dexp_se3(x))(ALL)
    # T is well conditioned for angles <= pi (cond ~ 10): roundoff only.
    err = _max_err(prod, jnp.eye(6)[None])
    assert err < 1e-12, f"dexp_se3_inv(x) @ dexp_se3(x) - I = {err:.3e}"


def test_dexp_so3_inv_is_inverse():
    prod = _batched(lambda w: lie.dexp_so3_inv(w) @ lie.dexp_so3(w))(ALL[:, :3])
    # Well conditioned for angles <= pi: roundoff only.
    err = _max_err(prod, jnp.eye(3)[None])
    assert err < 1e-12, f"dexp_so3_inv(w) @ dexp_so3(w) - I = {err:.3e}"


def test_dexp_se3_dot_matches_finite_differences():
    xs = jnp.concatenate([ZERO, TINY, RANDOM, SWITCH])
    ds = _random_twists(16, n=xs.shape[0])
    h = 1e-6
    ours = _batched(lie.dexp_se3_dot)(xs, ds)
    fd = _batched(
        lambda x, d: (lie.dexp_se3(x + h * d) - lie.dexp_se3(x - h * d)) / (2 * h)
    )(xs, ds)
    # Central differences with h=1e-6: ~1e-10 roundoff dominates.
    err = _max_err(ours, fd)
    assert err < 1e-8, f"dexp_se3_dot vs finite differences of dexp_se3: {err:.3e}"


# ---------------------------------------------------------------------------
# 6. Derivatives
# ---------------------------------------------------------------------------


def _log_se3_points():
    # Stay 1e-3 away from the cos(t) = 0 branch switch of log_so3: finite
    # differences in raw matrix entries leave the rotation manifold, where the two
    # branches are different (equally valid) extensions of log.
    angles = [PI / 2 - 1e-3, PI / 2 + 1e-3]
    off_switch = _twists_with_angles(jax.random.PRNGKey(21), angles)
    xs = jnp.concatenate([ZERO, TINY, RANDOM, off_switch])
    return _batched(lie.exp_se3)(xs)


JACOBIAN_CASES = {
    "exp_se3": (lie.exp_se3, lambda: ALL),
    "dexp_se3": (lie.dexp_se3, lambda: ALL),
    "log_se3": (lie.log_se3, _log_se3_points),
}


@pytest.mark.parametrize("name", sorted(JACOBIAN_CASES))
def test_jacobians_agree(name):
    f, points = JACOBIAN_CASES[name]
    xs = points()
    jf, jr, jn = _batched(
        lambda x: (jax.jacfwd(f)(x), jax.jacrev(f)(x), _central_jacobian(f, x))
    )(xs)
    assert bool(jnp.all(jnp.isfinite(jf))), f"jacfwd({name}) not finite"
    assert bool(jnp.all(jnp.isfinite(jr))), f"jacrev({name}) not finite"
    # Forward and reverse mode evaluate the same derivative code: roundoff only.
    err_fr = _max_err(jf, jr)
    assert err_fr < 1e-12, f"jacfwd vs jacrev of {name}: {err_fr:.3e}"
    # Central differences with h=1e-6: O(ulp/h) ~ 1e-10 roundoff dominates.
    err_fd = _max_err(jf, jn)
    assert err_fd < 1e-7, f"jacfwd vs finite differences of {name}: {err_fd:.3e}"


def _jit_vmap_hessian(f):
    return _batched(jax.hessian(f))


def _second_derivative_points():
    return jnp.concatenate([ZERO, TINY, _random_twists(17, n=2, max_angle=2.5), SWITCH])


SERIES_HESSIAN_CASES = {
    "exp_se3": (lie.exp_se3, _np_exp_series, (4, 4)),
    "dexp_se3": (lie.dexp_se3, _np_dexp_series, (6, 6)),
}


@pytest.mark.parametrize("name", sorted(SERIES_HESSIAN_CASES))
def test_hessian_matches_series(name):
    f, f_series, shape = SERIES_HESSIAN_CASES[name]
    weights = np.random.default_rng(18).normal(size=shape)
    xs = _second_derivative_points()
    ours = _jit_vmap_hessian(lambda x: jnp.sum(jnp.asarray(weights) * f(x)))(xs)
    assert bool(jnp.all(jnp.isfinite(ours))), f"hessian of {name} not finite"
    ref = np.stack(
        [_np_hessian(lambda y: np.sum(weights * f_series(y)), x) for x in xs]
    )
    # Reference: complex step + central difference (delta=1e-5) on the power
    # series, accurate to ~1e-10; closed forms are accurate to ~1e-12 there.
    err = float(np.max(np.abs(np.asarray(ours) - ref)))
    assert err < 1e-8, f"hessian of <W, {name}> vs series reference: {err:.3e}"


def _log_exp_points():
    return jnp.concatenate([ZERO, TINY, RANDOM, SWITCH, NEAR_PI[:1]])


def test_jacobian_of_log_exp_is_identity():
    xs = _log_exp_points()
    jac = _batched(jax.jacfwd(lambda x: lie.log_se3(lie.exp_se3(x))))(xs)
    # log(exp(x)) = x for |w| < pi; along the rotation manifold the derivative is
    # continuous across all log_so3 branches. Near pi (1e-6 away) the composite
    # loses ~1e-10 of accuracy through the conditioning of the axis extraction.
    err = _max_err(jac, jnp.eye(6)[None])
    assert err < 1e-8, f"jacobian of log_se3(exp_se3(x)) - I = {err:.3e}"


def test_second_derivative_of_log_exp_vanishes():
    xs = jnp.concatenate([ZERO, TINY, RANDOM, SWITCH])
    us = _random_twists(20, n=xs.shape[0])

    def second_directional(x, u):
        def first(y):
            return jax.jvp(lambda z: lie.log_se3(lie.exp_se3(z)), (y,), (u,))[1]

        return jax.jvp(first, (x,), (u,))[1]

    dd = _batched(second_directional)(xs, us)
    # log(exp(x)) = x, so every second directional derivative vanishes; second
    # derivatives of the closed forms are accurate to ~1e-12.
    assert bool(jnp.all(jnp.isfinite(dd))), "d2 log_se3(exp_se3(x)) not finite"
    err = float(jnp.max(jnp.abs(dd)))
    assert err < 1e-9, f"second derivative of log_se3(exp_se3(x)) = {err:.3e}"


def test_float32_support():
    @jax.jit
    def evaluate(x):
        hess = jax.hessian(lambda y: jnp.sum(lie.dexp_se3(y)))(jnp.zeros_like(x))
        return lie.exp_se3(x), lie.dexp_se3(x), hess

    x64 = RANDOM[0]
    exp32, dexp32, hess32 = evaluate(x64.astype(jnp.float32))
    exp64, dexp64, _ = evaluate(x64)
    for name, out, ref in [("exp_se3", exp32, exp64), ("dexp_se3", dexp32, dexp64)]:
        assert out.dtype == jnp.float32, f"{name} changed dtype to {out.dtype}"
        # float32 roundoff on O(1) entries.
        err = _max_err(out.astype(jnp.float64), ref)
        assert err < 1e-5, f"{name} float32 vs float64: {err:.3e}"
    assert bool(jnp.all(jnp.isfinite(hess32))), "float32 hessian at zero not finite"


# ---------------------------------------------------------------------------
# 7. jit / vmap consistency
# ---------------------------------------------------------------------------


# Zero, one random twist and one 1e-9 below angle pi (eager loops are slow).
FEW = ALL[jnp.array([0, 4, 8])]

TRANSFORMS = {
    "exp_so3": (lie.exp_so3, lambda: FEW[:, :3]),
    "log_so3": (lie.log_so3, lambda: _batched(lie.exp_so3)(FEW[:, :3])),
    "exp_se3": (lie.exp_se3, lambda: FEW),
    "log_se3": (lie.log_se3, lambda: _batched(lie.exp_se3)(FEW)),
    "dexp_se3": (lie.dexp_se3, lambda: FEW),
    "dexp_se3_inv": (lie.dexp_se3_inv, lambda: FEW),
    "Ad": (lie.Ad, lambda: _batched(lie.exp_se3)(FEW)),
}


@pytest.mark.parametrize("name", sorted(TRANSFORMS))
def test_jit_and_vmap_match_eager(name):
    f, points = TRANSFORMS[name]
    xs = points()
    eager = jnp.stack([f(x) for x in xs])
    jitted = jnp.stack([jax.jit(f)(x) for x in xs])
    vmapped = jax.vmap(f)(xs)
    # Compilation may reassociate/fuse floating point operations.
    assert _max_err(jitted, eager) < 1e-13, f"jit({name}) differs from eager"
    assert _max_err(vmapped, eager) < 1e-13, f"vmap({name}) differs from loop"
