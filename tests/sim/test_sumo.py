"""SUMO replay of recorded leaders: the imposed leader, insertion, model parameters, seeds."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from simcred.errors import MissingDependencyError, OptionError, TraceSetError
from simcred.io.openacc import read_openacc
from simcred.sim.sumo import (
    FOLLOWER_START,
    LENGTH,
    SumoModel,
    episode_seed,
    parse_model,
    replay,
    require_sumo,
    write_replays,
)
from simcred.traces import RUN_INFO, TraceSet, take

MODELS = ["Krauss", "IDM", "EIDM", "ACC"]


@pytest.fixture(scope="module")
def real():
    human = read_openacc(follower="human")
    return take(human, np.linspace(0, human.n_runs - 1, 6).astype(int))


@pytest.fixture(scope="module")
def replays(real):
    return replay(real, MODELS, seed=7, chunk_size=4)


def test_leader_speed_is_the_recorded_one_at_every_step(real, replays):
    for name in MODELS:
        sim = replays[name]
        assert sim.run_ids == real.run_ids and np.array_equal(sim.time, real.time)
        assert np.array_equal(sim.column("v_leader"), real.column("v_leader")), name


def test_start_state_is_the_recorded_one(real, replays):
    for sim in replays.values():
        for i in range(real.n_runs):
            a, b = sim.run(i), real.run(i)
            assert a["gap"][0] == pytest.approx(b["gap"][0], abs=1e-9)
            assert a["v"][0] == b["v"][0]


def test_leader_moves_by_its_recorded_speed(real, replays):
    """Euler update of SUMO: x[k] = x[k-1] + v[k] dt, so gap + follower travel is the oracle."""
    sim = replays["IDM"]
    for i in range(real.n_runs):
        run, rec = sim.run(i), real.run(i)
        dt = 0.1
        leader_x = FOLLOWER_START + rec["gap"][0] + LENGTH + dt * np.concatenate(
            [[0.0], np.cumsum(rec["v_leader"][1:])])
        follower_x = FOLLOWER_START + dt * np.concatenate([[0.0], np.cumsum(run["v"][1:])])
        assert np.allclose(leader_x - LENGTH - follower_x, run["gap"], atol=1e-6)


def _free_road(v0=10.0, steps=21) -> TraceSet:
    t = np.round(np.arange(steps) * 0.1, 1)
    return TraceSet.from_runs([{"t": t, "gap": np.full(steps, 300.0), "v": np.full(steps, v0),
                                "v_leader": np.full(steps, 30.0)}], run_ids=["free"])


@pytest.mark.parametrize("accel", [2.6, 1.0])
def test_krauss_without_dawdling_accelerates_at_accel(accel):
    """Krauss, sigma = 0, far leader: v[k] = v0 + k accel dt (the model's free-road law)."""
    model = SumoModel("Krauss", {"sigma": 0.0, "accel": accel})
    sim = replay(_free_road(), [model])["Krauss"]
    v = sim.run(0)["v"]
    assert np.allclose(v, 10.0 + accel * 0.1 * np.arange(len(v)), atol=1e-9)


def test_same_seed_same_output_in_any_chunking(real, replays):
    again = replay(real, ["Krauss"], seed=7, chunk_size=1)["Krauss"]
    assert again.digest() == replays["Krauss"].digest()
    other = replay(real, ["Krauss"], seed=8)["Krauss"]
    assert other.digest() != replays["Krauss"].digest()  # Krauss dawdles (sigma = 0.5)
    subset = replay(take(real, [3]), ["Krauss"], seed=7)["Krauss"]
    assert np.array_equal(subset.run(0)["v"], replays["Krauss"].run(3)["v"])


@pytest.mark.slow
def test_dask_equals_serial(real, replays):
    on_dask = replay(real, ["Krauss", "ACC"], seed=7, workers=2, chunk_size=2)
    for name in ("Krauss", "ACC"):
        assert on_dask[name].digest() == replays[name].digest()


def test_provenance(real, replays, tmp_path):
    sim = replays["EIDM"]
    info = sim.metadata[RUN_INFO][real.run_ids[0]]
    assert info["follower"] == "human"
    assert info["sumo_seed"] == episode_seed(7, real.run_ids[0])
    assert sim.metadata["input"]["digest"] == real.digest()
    paths = write_replays(replays, tmp_path, options={"seed": 7})
    back = TraceSet.read(paths[0])
    assert back.digest() == replays["Krauss"].digest()
    assert back.metadata[RUN_INFO] == replays["Krauss"].metadata[RUN_INFO]


def test_episode_seed_is_31_bit_and_keyed_by_run():
    seeds = {episode_seed(0, f"run{i}") for i in range(100)}
    assert len(seeds) == 100 and all(0 <= s < 2**31 for s in seeds)
    assert episode_seed(0, "a") == episode_seed(0, "a") != episode_seed(1, "a")


def test_parse_model():
    m = parse_model("IDM:tau=1.2,accel=1.5")
    assert (m.model, dict(m.params), m.name) == ("IDM", {"accel": 1.5, "tau": 1.2},
                                                 "IDM:tau=1.2,accel=1.5")
    with pytest.raises(OptionError, match="must be one of"):
        parse_model("Gipps")
    with pytest.raises(OptionError, match="NAME=NUMBER"):
        parse_model("IDM:tau")
    with pytest.raises(OptionError, match="not allowed"):
        SumoModel("IDM", {'x" y': 1.0})


def test_every_listed_model_is_one_sumo_runs(real):
    """The model list is SUMO's own: each replays an episode (IIDM was listed, SUMO has none)."""
    from simcred.sim.sumo import MODELS as LISTED

    one = take(real, [0])
    assert set(replay(one, list(LISTED), seed=1)) == set(LISTED)
    with pytest.raises(OptionError, match="must be one of"):
        parse_model("IIDM")


def test_bad_inputs(real):
    no_leader = TraceSet.from_runs([{"t": [0, 0.1], "gap": [5, 5], "v": [1, 1]}])
    with pytest.raises(TraceSetError, match="v_leader"):
        replay(no_leader, ["IDM"])
    uneven = TraceSet.from_runs([{"t": [0, 0.1, 0.3], "gap": [5, 5, 5], "v": [1, 1, 1],
                                  "v_leader": [1, 1, 1]}], run_ids=["r1"])
    with pytest.raises(TraceSetError, match="run 'r1': time steps are not uniform"):
        replay(uneven, ["IDM"])
    with pytest.raises(OptionError, match="repeat"):
        replay(real, ["IDM", "IDM"])


def test_cli_sumo_following(real, tmp_path, capsys):
    from simcred.cli import run

    src = real.write(tmp_path / "episodes.parquet")
    code = run(["--quiet", "simulate", "sumo-following", str(src), "--out", str(tmp_path / "o"),
                "--models", "IDM,Krauss:sigma=0+tau=1.2", "--seed", "7"])
    assert code == 0
    idm = TraceSet.read(tmp_path / "o" / "IDM.parquet")
    assert np.array_equal(idm.column("v_leader"), real.column("v_leader"))
    assert (tmp_path / "o" / "Krauss_sigma_0_tau_1_2.parquet").is_file()
    assert run(["simulate", "sumo-following", str(src), "--out", str(tmp_path / "p"),
                "--models", "Gipps"]) == 2
    assert "must be one of" in capsys.readouterr().err


def _episodes() -> TraceSet:
    t = np.arange(5) * 0.1
    return TraceSet.from_runs([{"t": t, "gap": np.full(5, 20.0), "v": np.full(5, 10.0),
                                "v_leader": np.full(5, 10.0)}], run_ids=["e"])


def test_a_missing_libsumo_is_one_user_error_line_naming_what_to_install(tmp_path, capsys,
                                                                          monkeypatch):
    from simcred.cli import run

    src = _episodes().write(tmp_path / "episodes.parquet")
    monkeypatch.setitem(sys.modules, "libsumo", None)  # `import libsumo` raises ImportError
    code = run(["simulate", "sumo-following", str(src), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "internal error" not in err
    assert "SUMO is not installed" in err and "pip install eclipse-sumo libsumo" in err
    with pytest.raises(MissingDependencyError, match="libsumo"):
        replay(_episodes(), ["IDM"])


def test_a_missing_netconvert_names_eclipse_sumo(monkeypatch):
    import importlib.metadata
    import shutil

    def absent(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "distribution", absent)
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(MissingDependencyError, match="netconvert .*pip install eclipse-sumo"):
        require_sumo()
