"""Guards of issue 24 item 4: units from the data's own positions, optional speed and heading
columns, the step limit on every resimulation, and no world coordinates without a road frame."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from simcred.cli import run
from simcred.errors import SimcredError
from simcred.kinematics import Track
from simcred.reprocess.inputs import LongColumns, long_drive
from simcred.reprocess.timebase import Drive, RecordedTracks
from simcred.reprocess.units import check_units
from simcred.scenario.fit import fit_scenario
from simcred.sim.resimulation import time_grid

STEP = 0.1
T = np.round(np.arange(0.0, 6.0 + STEP / 2, STEP), 10)
OBJECTS = ("ego", "to")


def _drive_columns(angle: float = 0.0) -> dict[str, dict[str, np.ndarray]]:
    """EGO at 20 m/s along +x; TO 25 m ahead at 15 m/s changing lane (y = 3.5 → 0, a cosine);
    the whole scene rotated by ``angle`` about the origin (world coordinates)."""
    y_to = 1.75 * (1 + np.cos(np.pi * np.clip(T / 4, 0, 1)))
    vy_to = -1.75 * np.pi / 4 * np.sin(np.pi * np.clip(T / 4, 0, 1)) * (T < 4)
    scene = {"ego": (20 * T, np.zeros_like(T), np.full_like(T, 20.0), np.zeros_like(T)),
             "to": (25 + 15 * T, y_to, np.hypot(15, vy_to), np.arctan2(vy_to, 15))}
    c, s = math.cos(angle), math.sin(angle)
    return {name: {"x": c * x - s * y, "y": s * x + c * y, "v": v, "heading": h + angle}
            for name, (x, y, v, h) in scene.items()}


def _table(path: Path, columns: dict[str, dict[str, np.ndarray]], *, time_factor: float = 1.0,
           signals=("x", "y", "v", "heading")) -> Path:
    lines = [",".join(["t", "object", *signals])]
    for k, t in enumerate(T):
        for name in OBJECTS:
            lines.append(",".join([repr(float(t * time_factor)), name,
                                   *(repr(float(columns[name][s][k])) for s in signals)]))
    path.write_text("\n".join(lines) + "\n")
    return path


def _recording(columns: dict[str, dict[str, np.ndarray]]) -> Drive:
    tracks = {n: Track(T, c["x"], c["y"], c["v"], c["heading"]) for n, c in columns.items()}
    return Drive(RecordedTracks("rec", tracks, "sha256:test"))


def _one_line_exit_2(args: list[str], capsys) -> str:
    assert run(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    return err


def test_si_units_pass():
    check_units(_recording(_drive_columns()), OBJECTS)


def test_timestamps_in_milliseconds_are_one_line_or_a_stated_conversion(tmp_path, capsys):
    path = _table(tmp_path / "ms.csv", _drive_columns(), time_factor=1000.0)
    err = _one_line_exit_2(["reprocess", str(path), "--object-column", "object",
                            "--out", str(tmp_path / "o")], capsys)
    assert "median sample step 100" in err and "--time-scale 0.001" in err
    drive = long_drive(path, LongColumns(object_column="object", time_scale=0.001))
    np.testing.assert_allclose(drive.sd.tracks["to"].t, T, atol=1e-12)
    assert drive.metadata["time_scale"] == 0.001
    check_units(drive, OBJECTS)


@pytest.mark.parametrize("factor, unit", [(3.6, "km/h"), (1 / 0.44704, "mph"), (0.3, "")])
def test_a_speed_that_disagrees_with_the_positions_is_refused(factor, unit):
    columns = _drive_columns()
    columns["to"]["v"] = columns["to"]["v"] * factor
    with pytest.raises(SimcredError, match="object 'to': speed v is") as info:
        check_units(_recording(columns), OBJECTS)
    assert f"{factor:.3g} ×" in str(info.value)
    assert (f"looks like {unit}" in str(info.value)) == bool(unit)


def test_heading_in_degrees_is_refused_even_near_zero():
    columns = _drive_columns()
    columns["to"]["heading"] = np.degrees(columns["to"]["heading"])  # 0 … -34°
    with pytest.raises(SimcredError, match="object 'to': heading looks like degrees"):
        check_units(_recording(columns), OBJECTS)


def test_a_heading_off_the_direction_of_travel_is_refused():
    columns = _drive_columns(-0.68)  # read as degrees the heading would not fit either
    columns["ego"]["heading"] = columns["ego"]["heading"] + math.pi / 2
    with pytest.raises(SimcredError, match=r"object 'ego': heading is 1\.57 rad"):
        check_units(_recording(columns), OBJECTS)


def test_speed_and_heading_columns_are_optional_and_derived_from_positions(tmp_path):
    path = _table(tmp_path / "xy.csv", _drive_columns(), signals=("x", "y"))
    drive = long_drive(path, LongColumns(object_column="object"))
    assert drive.metadata["derived"] == ["heading", "v"]
    to = drive.sd.tracks["to"]
    x, y = _drive_columns()["to"]["x"], _drive_columns()["to"]["y"]
    k = 20  # an inner sample: central differences, literally
    vx, vy = (x[k + 1] - x[k - 1]) / (2 * STEP), (y[k + 1] - y[k - 1]) / (2 * STEP)
    assert to.v[k] == pytest.approx(math.hypot(vx, vy), rel=1e-12)
    assert to.heading[k] == pytest.approx(math.atan2(vy, vx), abs=1e-12)
    assert to.v[0] == pytest.approx(math.hypot(x[1] - x[0], y[1] - y[0]) / STEP, rel=1e-12)


def test_world_coordinates_are_refused_or_rotated_into_the_egos_direction(tmp_path, capsys):
    world = _table(tmp_path / "world.csv", _drive_columns(-0.68))
    err = _one_line_exit_2(["reprocess", str(world), "--object-column", "object",
                            "--out", str(tmp_path / "o")], capsys)
    assert "EGO travels at -0.68 rad" in err and "--road-frame ego" in err
    road = _table(tmp_path / "road.csv", _drive_columns())
    rotated = long_drive(world, LongColumns(object_column="object", road_frame="ego"))
    plain = long_drive(road, LongColumns(object_column="object"))
    assert rotated.metadata["frame"]["angle"] == pytest.approx(-0.68, abs=1e-12)
    for name in OBJECTS:  # the rotation undoes the world frame (origin: the EGO's start, 0)
        a, b = rotated.sd.tracks[name], plain.sd.tracks[name]
        for signal in ("x", "y", "v", "heading"):
            np.testing.assert_allclose(getattr(a, signal), getattr(b, signal), atol=1e-9)


def test_every_resimulation_is_held_to_the_step_limit(monkeypatch):
    columns = _drive_columns()
    description = fit_scenario({n: (T, c["x"], c["y"]) for n, c in columns.items()}).description
    steps = round((description.t1 - description.t0) / 0.01) + 1  # 601: 0, 0.01, …, 6 s
    monkeypatch.setenv("SIMCRED_MAX_STEPS", str(steps))
    assert len(time_grid(description, 0.01)) == steps == 601
    monkeypatch.setenv("SIMCRED_MAX_STEPS", str(steps - 1))
    with pytest.raises(SimcredError, match=f"steps = {steps} exceeds the limit of {steps - 1}"):
        time_grid(description, 0.01)
