"""The known-truth designs of the validate study (tests/validate_designs.py) are what they say."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import validate_designs as vd
from simcred.traces import RUN_INFO


def _rng(seed=0):
    return np.random.default_rng(seed)


def _matrix(traces, signal):
    return traces.column(signal).reshape(traces.n_runs, -1)


def _xcorr_peak(response, leader, lags=15):
    """Lag (steps) of the largest cross-covariance of the increments of ``response`` with the
    earlier increments of ``leader`` (both (runs, samples))."""
    dr, dl = np.diff(response, axis=1), np.diff(leader, axis=1)
    xc = [np.mean(dr[:, k:] * dl[:, :dl.shape[1] - k]) for k in range(lags)]
    return int(np.argmax(xc)), np.asarray(xc) / max(xc)


def test_noise_has_the_human_drivers_sd_and_correlation_time():
    assert np.isclose(vd.PHI ** 5, vd.HUMAN.phi)  # 5 steps of 0.1 s = one step of 0.5 s
    assert np.isclose(vd.TAU, -vd.DT / np.log(vd.PHI))  # the same correlation time
    d = vd.human(_rng(), 7)
    assert d.sigma == vd.HUMAN.sigma and d.phi == vd.PHI and np.shape(d.T) == (7,)
    # the applied acceleration minus the command is the noise: stationary sd 0.2, lag-1 corr phi
    leaders = vd.draw_windows(_rng(1), 200)
    gap0, v0 = vd.start_state(leaders["v_leader"])
    sim = vd.simulate(_rng(2), leaders["v_leader"], gap0, v0, d := vd.human(_rng(3), 200))
    noise = sim["a"] - sim["command"]
    assert noise.std() == pytest.approx(d.sigma, rel=0.1)
    lag1 = np.corrcoef(noise[:, 1:].ravel(), noise[:, :-1].ravel())[0, 1]
    assert lag1 == pytest.approx(vd.PHI, abs=0.01)


def test_closed_loop_pair_shapes_units_and_facts():
    ref, cand = vd.closed_loop_pair(_rng(), 12, defect="delay_0.3")
    samples = vd.samples_of(vd.WINDOW)
    assert samples == 251
    for s in (ref, cand):
        assert s.signals == ("gap", "dv", "v", "a", "v_leader")
        assert s.n_runs == 12 and s.n_rows == 12 * samples
        assert np.allclose(s.time[:3], [0.0, 0.1, 0.2])
        assert s.metadata["units"] == {"gap": "m", "dv": "m/s", "v": "m/s", "a": "m/s²",
                                       "v_leader": "m/s"}
        info = s.metadata[RUN_INFO][s.run_ids[0]]
        assert {"file", "leader_vehicle", "track", "start_sample", "offset", "T"} <= set(info)
        assert np.allclose(s.column("dv"), s.column("v_leader") - s.column("v"))
    assert cand.metadata[RUN_INFO][cand.run_ids[0]]["defect"] == "delay_0.3"
    with pytest.raises(ValueError, match="unknown defect"):
        vd.closed_loop_pair(_rng(), 3, defect="delay_0.2")


def test_pairs_replay_the_same_leader_from_the_same_start():
    ref, cand = vd.closed_loop_pair(_rng(4), 20, defect="none")
    assert ref.run_ids == cand.run_ids
    assert np.array_equal(ref.column("v_leader"), cand.column("v_leader"))
    for key in ("file", "leader_vehicle", "track", "start_sample", "offset"):
        assert [ref.metadata[RUN_INFO][r][key] for r in ref.run_ids] == \
            [cand.metadata[RUN_INFO][r][key] for r in cand.run_ids]
    first = ref.offsets[:-1]
    for signal in ("gap", "v"):
        assert np.array_equal(ref.column(signal)[first], cand.column(signal)[first])
    # own noise and own headway: the runs differ after the start
    assert not np.allclose(ref.column("a"), cand.column("a"))
    assert not np.allclose([ref.metadata[RUN_INFO][r]["T"] for r in ref.run_ids],
                           [cand.metadata[RUN_INFO][r]["T"] for r in cand.run_ids])


def test_leader_windows_are_recorded_profiles_shifted_into_range():
    leaders = vd.draw_windows(_rng(5), 300)
    vl = leaders["v_leader"]
    assert vl.min() >= 0 and vl.max() <= vd.V_MAX + 1e-9
    assert vl.min() < 5 and vl.max() > 25  # spans the speeds of both cells
    assert 0.3 < np.mean(vl < 15) < 0.7
    raw = vd.draw_windows(_rng(5), 300, shift=False)
    assert np.array_equal(raw["track"], leaders["track"])
    assert np.allclose(vl - raw["v_leader"], leaders["offset"][:, None])
    k, s = int(raw["track"][0]), int(raw["start"][0])
    assert np.array_equal(raw["v_leader"][0], vd.tracks().v_leader[k][s:s + vl.shape[1]])
    assert len({(int(a), int(b)) for a, b in zip(raw["track"], raw["start"], strict=True)}) == 300


@pytest.mark.parametrize("defect", ["none", "delay_0.15", "delay_0.3", "delay_0.5", "delay_1.0"])
def test_the_delay_delays_the_command(defect):
    """A leader with white accelerations: the command's increments follow the leader's
    increments ``delay / dt`` steps later (0.15 s: split between 1 and 2 steps)."""
    vl = 15 + np.cumsum(_rng(6).normal(0, 0.05, size=(40, 300)), axis=1)
    gap0, v0 = vd.start_state(vl)
    driver = replace(vd.human(_rng(7), 40), sigma=0.0)
    sim = vd.simulate(_rng(8), vl, gap0, v0, driver, **vd.defect_options(defect))
    peak, xc = _xcorr_peak(sim["command"], vl)
    steps = vd.DELAYS.get(defect, 0.0) / vd.DT
    if np.isclose(steps, round(steps)):
        assert peak == round(steps)
        assert np.delete(xc, peak).max() < 0.2
    else:
        lo = int(np.floor(steps))
        assert peak in (lo, lo + 1) and min(xc[lo], xc[lo + 1]) > 0.9
        assert np.delete(xc, [lo, lo + 1]).max() < 0.2


def test_the_delay_shows_behind_recorded_leaders():
    peaks = {}
    for defect in ("none", "delay_0.5", "delay_1.0"):
        _, cand = vd.closed_loop_pair(_rng(3), 100, defect=defect)
        peaks[defect], _ = _xcorr_peak(_matrix(cand, "a"), _matrix(cand, "v_leader"))
    assert peaks["none"] < peaks["delay_0.5"] < peaks["delay_1.0"]
    assert peaks["delay_1.0"] == pytest.approx(10, abs=2)


def test_clip_bounds_hold_and_bite():
    ref, cand = vd.closed_loop_pair(_rng(9), 300, defect="clip")
    a = cand.column("a")
    lo, hi = vd.CLIP
    assert a.min() >= lo - 1e-12 and a.max() <= hi + 1e-12
    assert np.mean(a >= hi - 1e-12) > 0.02  # the upper clip is reached
    assert np.mean(ref.column("a") > hi) > 0.02  # where the reference accelerates harder
    assert not vd.crashed(cand).any() and not vd.crashed(ref).any()
    _, sym = vd.closed_loop_pair(_rng(9), 300, defect="clip_0.5")
    assert np.abs(sym.column("a")).max() <= 0.5 + 1e-12


def test_determinism_and_common_random_numbers():
    a1, b1 = vd.closed_loop_pair(_rng(11), 15, defect="delay_0.5")
    a2, b2 = vd.closed_loop_pair(_rng(11), 15, defect="delay_0.5")
    assert a1.equals(a2) and b1.equals(b2)
    a3, b3 = vd.closed_loop_pair(_rng(11), 15, defect="clip")
    assert a3.equals(a1)  # the same reference whatever the defect
    assert not b3.equals(b1)
    a4, _ = vd.closed_loop_pair(_rng(12), 15)
    assert not a4.equals(a1)
    h1, h2 = vd.human_halves(_rng(3), 40), vd.human_halves(_rng(3), 40)
    assert h1[0].equals(h2[0]) and h1[1].equals(h2[1])


def _units(traces):
    return {traces.metadata[RUN_INFO][r]["unit"] for r in traces.run_ids}


def test_human_halves_are_disjoint_by_unit_and_stratified_by_file():
    eps = vd.human_episodes()
    assert eps.n_runs == 609 and len({i["unit"] for i in eps.metadata[RUN_INFO].values()}) == 24
    a, b = vd.human_halves(_rng(0))
    assert a.n_runs + b.n_runs == 609  # None: every episode
    assert not _units(a) & _units(b) and len(_units(a) | _units(b)) == 24
    assert not set(a.run_ids) & set(b.run_ids)
    files = [{s.metadata[RUN_INFO][r]["file"] for r in s.run_ids} for s in (a, b)]
    assert files[0] == files[1] and len(files[0]) == 4
    for r in a.run_ids:  # the unit is the follower in one recording
        info = a.metadata[RUN_INFO][r]
        assert info["unit"] == f"{info['file']}:{info['follower_position']}"
    small = vd.human_halves(_rng(1), 10)
    assert [s.n_runs for s in small] == [10, 10]
    assert not _units(small[0]) & _units(small[1])
    capped = vd.human_halves(_rng(1), 10_000)
    assert sum(s.n_runs for s in capped) == 609
    # different seeds give different splits
    assert _units(vd.human_halves(_rng(5))[0]) != _units(a)
