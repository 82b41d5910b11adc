"""MDF4 files written by asammdf: values against numpy, resampling stated or refused, runs from a
run channel or from files, units, `simcred compare` on two files, and 20 malformed files."""

from __future__ import annotations

import gc
from pathlib import Path

import numpy as np
import pytest
from asammdf import MDF, Signal

from fuzz.test_cli_fuzz import run_isolated
from helpers import cli_compare_known_answer
from simcred.cli import run
from simcred.errors import OptionError, TraceSetError
from simcred.io import detect, read
from simcred.traces import TraceSet


def write_mdf(path: Path, groups: list[list[Signal]]) -> Path:
    mdf = MDF(version="4.10")
    for signals in groups:
        mdf.append(signals)
    mdf.save(str(path), overwrite=True)
    mdf.close()
    return path


def two_rates(path: Path) -> Path:
    """speed at 100 Hz with a run channel (runs 0 and 1), yaw at 10 Hz."""
    fast, slow = np.arange(100) * 0.01, np.arange(11) * 0.1
    return write_mdf(path, [
        [Signal(2.0 * fast, fast, name="speed", unit="km/h"),
         Signal((np.arange(100) // 50).astype(np.uint8), fast, name="run")],
        [Signal(3.0 * slow ** 2, slow, name="yaw", unit="rad")]])


def test_different_rates_are_refused_without_a_method(tmp_path):
    path = two_rates(tmp_path / "drive.mf4")
    assert detect(path).name == "mdf"
    with pytest.raises(TraceSetError, match=r"drive.mf4: channels 'speed' \(100 Hz, group 0\) "
                                            r"and 'yaw' \(10 Hz, group 1\) have different"):
        read(path)


@pytest.mark.parametrize("method", ["linear", "previous"])
def test_resampling_puts_channels_on_the_fastest_base_with_the_method_stated(tmp_path, method):
    ts = read(two_rates(tmp_path / "drive.mf4"), resample=method)
    fast, slow = np.arange(100) * 0.01, np.arange(11) * 0.1
    assert ts.run_ids == ("0", "1") and ts.lengths.tolist() == [50, 50]
    assert ts.time.tolist() == fast.tolist()
    assert ts.column("speed").tolist() == (2.0 * fast).tolist()
    if method == "linear":
        expected = np.interp(fast, slow, 3.0 * slow ** 2)
    else:  # the last 10 Hz sample at or before each 100 Hz time stamp
        expected = np.array([3.0 * slow[np.flatnonzero(slow <= t)[-1]] ** 2 for t in fast])
    assert ts.column("yaw").tolist() == expected.tolist()
    assert ts.metadata["resampling"] == {"method": method, "base": "speed", "base_group": 0,
                                         "rate_hz": pytest.approx(100.0)}
    assert ts.units == {"speed": "km/h", "yaw": "rad"}


def test_channel_selection_and_one_run_without_run_channel(tmp_path):
    ts = read(two_rates(tmp_path / "drive.mf4"), channels=["yaw"], run_channel="none")
    assert ts.signals == ("yaw",) and ts.run_ids == ("drive",)
    assert ts.time.tolist() == (np.arange(11) * 0.1).tolist()
    with pytest.raises(TraceSetError, match=r"no channel 'pitch' \(channels: run, speed, yaw\)"):
        read(tmp_path / "drive.mf4", channels=["pitch"])
    with pytest.raises(OptionError, match="resample must be one of linear, previous"):
        read(tmp_path / "drive.mf4", resample="cubic")


def test_run_channel_groups_samples_by_first_appearance(tmp_path):
    t = np.arange(6) * 0.5
    path = write_mdf(tmp_path / "r.mf4", [[Signal(t * 10, t, name="v", unit="m/s"),
                                            Signal(np.array([7, 7, 3, 3, 7, 7]), t, name="run")]])
    ts = read(path)
    assert ts.run_ids == ("7", "3")
    assert ts.run(0)["t"].tolist() == [0.0, 0.5, 2.0, 2.5]
    assert ts.run(0)["v"].tolist() == [0.0, 5.0, 20.0, 25.0]
    assert ts.run(1)["v"].tolist() == [10.0, 15.0]


def test_a_directory_of_files_is_one_run_per_file(tmp_path):
    t = np.arange(4) * 0.1
    folder = tmp_path / "drives"
    folder.mkdir()
    for k in (10, 2):
        write_mdf(folder / f"drive_{k}.mf4", [[Signal(t + k, t, name="v", unit="m/s")]])
    assert detect(folder).name == "mdf"
    ts = read(folder)
    assert ts.run_ids == ("drive_2", "drive_10")  # natural order
    assert ts.column("v").tolist() == (t + 2).tolist() + (t + 10).tolist()
    assert ts.units == {"v": "m/s"}


def test_ambiguous_channel_name_is_refused(tmp_path):
    t = np.arange(3) * 0.1
    path = write_mdf(tmp_path / "amb.mf4", [[Signal(t, t, name="v")], [Signal(t, t, name="v")]])
    with pytest.raises(TraceSetError, match="channel 'v' is in channel groups 0, 1"):
        read(path)


# -- simcred compare on two MDF4 files: a known answer ---------------------------------------------


def drives(path: Path, seed: int, phi: float) -> Path:
    """40 runs of an AR(1) speed trace in one file, runs named by a run channel."""
    rng = np.random.default_rng(seed)
    speeds, runs = [], []
    for k in range(40):
        x = [rng.normal()]
        for _ in range(29):
            x.append(phi * x[-1] + rng.normal())
        speeds += x
        runs += [k] * 30
    t = np.arange(len(speeds)) * 0.1
    return write_mdf(path, [[Signal(np.array(speeds), t, name="v", unit="m/s"),
                             Signal(np.array(runs, dtype=np.uint16), t, name="run")]])


@pytest.mark.parametrize("phi_b, same", [(0.8, True), (-0.8, False)])
def test_cli_compare_on_two_mdf4_files(tmp_path, capsys, phi_b, same):
    a = drives(tmp_path / "a.mf4", seed=1, phi=0.8)
    b = drives(tmp_path / "b.mf4", seed=1, phi=phi_b)  # same seed: b is a's copy when same
    doc = cli_compare_known_answer(capsys, a, b, "v", same)
    assert doc["units"] == ["m/s"]


def test_convert_with_resample_method_records_it(tmp_path, capsys):
    source = two_rates(tmp_path / "drive.mf4")
    assert run(["--quiet", "convert", str(source), str(tmp_path / "d.parquet"),
                "--resample-method", "previous"]) == 0
    back = TraceSet.read(tmp_path / "d.parquet")
    assert back.metadata["resampling"]["method"] == "previous"
    assert back.metadata["converted_from"]["options"] == {"resample": "previous"}


# -- malformed files: one line, exit 2 -------------------------------------------------------------


def _bytes(change):
    def build(good: Path, bad: Path) -> list[str]:
        bad.write_bytes(change(good.read_bytes()))
        return ["compare", str(bad), str(bad), "-f", "v"]
    return build


def _mdf(groups, *options):
    def build(good: Path, bad: Path) -> list[str]:
        write_mdf(bad, groups)
        return ["convert", str(bad), str(bad.with_suffix(".parquet")), *options]
    return build


T = np.arange(5) * 0.1
MALFORMED = {
    "empty": _bytes(lambda b: b""),
    "truncated 64": _bytes(lambda b: b[:64]),
    "truncated half": _bytes(lambda b: b[: len(b) // 2]),
    "truncated end": _bytes(lambda b: b[:-40]),
    "random bytes": _bytes(lambda b: np.random.default_rng(0).bytes(len(b))),
    "text": _bytes(lambda b: b"t,v\n0,1\n1,2\n"),
    "wrong magic": _bytes(lambda b: b"XXXXXXXX" + b[8:]),
    "encrypted body": _bytes(lambda b: b[:64] + bytes(x ^ 0x5A for x in b[64:])),
    "zeroed blocks": _bytes(lambda b: b[:64] + bytes(len(b) - 64)),
    "scrambled header": _bytes(lambda b: b[:64] + bytes(reversed(b[64:200])) + b[200:]),
    "unknown channel": _mdf([[Signal(T, T, name="v")]], "--channels", "w"),
    "rates differ": _mdf([[Signal(T, T, name="v")], [Signal(T[:3], T[:3] * 2, name="w")]]),
    "bad method": _mdf([[Signal(T, T, name="v")]], "--resample-method", "cubic"),
    "text channel": _mdf([[Signal(np.array([b"a", b"b", b"c", b"d", b"e"]), T, name="v",
                                 encoding="utf-8")]],
                         "--channels", "v"),
    "nan sample": _mdf([[Signal(np.array([0, 1, np.nan, 3, 4.0]), T, name="v")]]),
    "repeated time": _mdf([[Signal(T, np.array([0, 0.1, 0.1, 0.2, 0.3]), name="v")]]),
    "one sample": _mdf([[Signal(T[:1], T[:1], name="v")]]),
    "nan run channel": _mdf([[Signal(T, T, name="v"),
                              Signal(np.array([0, 0, np.nan, 1, 1]), T, name="run")]]),
    "only run channel": _mdf([[Signal(np.zeros(5), T, name="run")]]),
    "ambiguous": _mdf([[Signal(T, T, name="v")], [Signal(T, T, name="v")]]),
}


@pytest.mark.parametrize("name", list(MALFORMED))
def test_malformed_mdf_is_one_line_exit_2(tmp_path, name):
    good = drives(tmp_path / "good.mf4", seed=0, phi=0.5)
    argv = MALFORMED[name](good, tmp_path / "corrupt_m.mf4")
    code, out, err, elapsed = run_isolated(argv, 10)
    assert code is not None, "hang"
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, (code, err[-400:])
    assert len(lines) == 1 and lines[0].startswith("error:"), err[-400:]
    assert "Traceback" not in err + out
    if argv[0] == "compare" or "--resample-method" not in argv:
        assert "corrupt_m" in lines[0], lines[0]


@pytest.mark.parametrize("name", ["truncated half", "zeroed blocks", "unknown channel"])
def test_a_damaged_file_leaves_nothing_on_stderr(tmp_path, capsys, name):
    # asammdf's half-built reader raises in __del__; Python would print "Exception ignored"
    good = drives(tmp_path / "good.mf4", seed=0, phi=0.5)
    argv = MALFORMED[name](good, tmp_path / "corrupt_m.mf4")
    with pytest.raises(TraceSetError, match="corrupt_m.mf4: (unreadable MDF|no channel 'w')"):
        read(tmp_path / "corrupt_m.mf4", **({"channels": ["w"]} if "--channels" in argv else {}))
    gc.collect()
    assert capsys.readouterr().err == ""


def test_twenty_malformed_cases():
    assert len(MALFORMED) == 20
