"""The refit's caches (issue 24: the variation campaign refits at the same times): every cached
piece gives the bytes of the literal computation, cold or warm, and cannot be written to."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import BSpline

from simcred.scenario import fit_robust, fit_support, plausibility, spline
from simcred.scenario.description import ObjectTrack, sample_times
from simcred.scenario.fit import fit_track
from simcred.scenario.fit_support import _local_acceleration_loop, local_acceleration
from simcred.scenario.plausibility import PLAUSIBILITY_DT, check_plausibility
from simcred.scenario.spline import Quadrature, Spline, design_matrix, spline_knots


def _clear() -> None:
    for cached in (spline._design_cached, spline._quadrature_cached, spline._knots,
                   fit_robust._predictors_cached, fit_support._windows_cached,
                   plausibility._default_rates):
        cached.cache_clear()


def _track(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 12.0, 241)
    return t, 18.0 * t + 0.3 * np.sin(t) + rng.normal(0, 0.01, t.size), \
        1.5 * np.tanh(t - 6.0) + rng.normal(0, 0.01, t.size)


def test_design_matrix_is_the_literal_basis_and_a_writable_copy():
    _clear()
    t = np.linspace(0.0, 5.0, 37)
    literal = BSpline.design_matrix(t, spline_knots(0.0, 5.0, 4), 3).toarray()
    for _ in range(2):  # cold, then warm
        basis = design_matrix(0.0, 5.0, 4, t)
        assert basis.tobytes() == literal.tobytes() and basis.flags.writeable
        basis[:] = 0.0  # the cache is not touched
    assert spline._design(0.0, 5.0, 4, t).tobytes() == literal.tobytes()
    with pytest.raises(ValueError):
        spline._design(0.0, 5.0, 4, t)[0, 0] = 1.0


def test_quadrature_is_shared_read_only_and_as_built_anew():
    _clear()
    t = np.linspace(0.0, 3.0, 31)
    literal = Quadrature._build(0.0, 3.0, 2, t)
    a, b = Quadrature.build(0.0, 3.0, 2, t), Quadrature.build(0.0, 3.0, 2, t.copy())
    assert a is b
    for name in ("grid", "full_nodes", "full_weights", "index", "part_nodes", "part_weights"):
        assert getattr(a, name).tobytes() == getattr(literal, name).tobytes()
        assert not getattr(a, name).flags.writeable


def test_spikes_and_local_acceleration_cached_equal_the_literal_computation():
    _clear()
    t, x, y = _track()
    loop = _local_acceleration_loop(t, x, y, 0.02)
    for _ in range(2):
        accel, error = local_acceleration(t, x, y, 0.02)
        np.testing.assert_allclose(accel, loop[0], rtol=1e-9)
        np.testing.assert_allclose(error, loop[1], rtol=1e-9)
    first = fit_robust.spikes(t, x, y)
    fit_robust._predictors_cached.cache_clear()
    assert fit_robust.spikes(t, x, y).tobytes() == first.tobytes()
    uncached = fit_robust._predictors_of(t)
    for cached, fresh in zip(fit_robust._predictors(t), uncached, strict=True):
        assert all(a.tobytes() == b.tobytes() for a, b in zip(cached, fresh, strict=True))


def test_plausibility_default_grid_cached_equals_sampling_at_given_times():
    _clear()
    track = ObjectTrack(1.0, 2.0, Spline(0.0, 6.0, [5.0, 9.0, 40.0, 3.0, 8.0]),
                        Spline(0.0, 6.0, [0.0, 0.4, -0.3, 2.0, 0.1]))
    times = sample_times(0.0, 6.0, PLAUSIBILITY_DT)
    literal = check_plausibility(track, t=times)
    assert literal  # violates something, so that the comparison means something
    assert check_plausibility(track) == literal == check_plausibility(track)
    assert plausibility._default_rates.cache_info().hits >= 1


def test_fit_track_cold_and_warm_caches_give_identical_fits():
    t, x, y = _track(1)
    fits = []
    for clear in (True, False, True):
        if clear:
            _clear()
        fits.append(fit_track(t, x, y))
    for f in fits[1:]:
        assert f.track.speed.coefficients.tobytes() == fits[0].track.speed.coefficients.tobytes()
        assert f.track.heading.coefficients.tobytes() == \
            fits[0].track.heading.coefficients.tobytes()
        assert (f.track.x0, f.track.y0, f.rmse, f.iterations, f.glitches) == \
            (fits[0].track.x0, fits[0].track.y0, fits[0].rmse, fits[0].iterations,
             fits[0].glitches)


def _spikes_literal(t, x, y):
    """spikes() as written before the cache (one pinv per call)."""
    n, best = len(t), np.full(len(t), np.inf)
    for offsets in fit_robust._SUBSETS:
        j = np.arange(n)[:, None] + offsets
        valid = (j >= 0) & (j < n)
        jj = np.clip(j, 0, n - 1)
        dt = np.where(valid, t[jj] - t[:, None], 0.0)
        s = dt / np.maximum(np.abs(dt).max(axis=1, keepdims=True), 1e-12)
        w = valid.astype(float)
        usable = valid.sum(axis=1) >= 3
        c0 = np.linalg.pinv(np.stack([w, w * s, w * s * s], axis=-1)[usable])[:, 0, :]
        px = np.einsum("nk,nk->n", c0, (w * x[jj])[usable])
        py = np.einsum("nk,nk->n", c0, (w * y[jj])[usable])
        best[usable] = np.minimum(best[usable], np.hypot(px - x[usable], py - y[usable]))
    return best


def test_spikes_are_the_literal_bytes_cold_and_warm():
    _clear()
    t, x, y = _track(2)
    literal = _spikes_literal(t, x, y)
    assert fit_robust.spikes(t, x, y).tobytes() == literal.tobytes()
    assert fit_robust.spikes(t, x, y).tobytes() == literal.tobytes()


def test_spline_least_squares_cached_is_the_literal_solution():
    _clear()
    spline._least_squares_cached.cache_clear()
    t, x, _ = _track(3)
    w = np.linspace(0.5, 2.0, t.size)
    for weights in (None, w):
        basis = BSpline.design_matrix(t, spline_knots(0.0, 12.0, 5), 3).toarray()
        b, v = (basis, x) if weights is None else (basis * np.sqrt(w)[:, None], x * np.sqrt(w))
        literal = np.linalg.lstsq(b, v, rcond=None)[0]
        for _ in range(2):
            s = Spline.least_squares(t, x, t0=0.0, t1=12.0, sections=5, weights=weights)
            assert s.coefficients.tobytes() == literal.tobytes()
    assert spline._least_squares_cached.cache_info().hits == 2


def test_object_track_states_cached_are_fresh_copies_of_the_literal_states():
    from simcred.scenario import description as description_module

    description_module._states_cached.cache_clear()
    track = ObjectTrack(1.0, 2.0, Spline(0.0, 6.0, [5.0, 9.0, 14.0, 3.0, 8.0]),
                        Spline(0.0, 6.0, [0.0, 0.4, -0.3, 2.0, 0.1]))
    t = np.linspace(0.0, 6.0, 601)
    literal = track._states(t.copy())
    first, second = track.states(t), track.states(t)
    assert description_module._states_cached.cache_info().hits == 1
    for name in description_module._STATE_COLUMNS:
        assert getattr(first, name).tobytes() == getattr(literal, name).tobytes()
        assert getattr(second, name).tobytes() == getattr(literal, name).tobytes()
        assert getattr(first, name).flags.writeable
    first.x[:] = 0.0  # a caller's copy: the next call is unaffected
    assert track.states(t).x.tobytes() == literal.x.tobytes()
