"""Generated files: every reader either returns a valid result or raises one SimcredError line.

Hypothesis builds CSV run files, Parquet tables and YAML documents from cells, names and
structures that users' tools actually produce (empty cells, quotes, non-ASCII, huge or
non-finite numbers, duplicate or missing columns, nesting); no other exception may escape.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simcred.contracts.library import Library
from simcred.errors import SimcredError
from simcred.traces import TraceSet
from simcred.validate.spec import read_validation

CELLS = st.one_of(
    st.integers(-10**6, 10**6).map(str), st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", "nan", "inf", "-0", "1e400", "1,5", '"2"', "true", " 3 ", "9" * 400]),
    st.text(max_size=8))
NAMES = st.one_of(st.sampled_from(["t", "x", "y", "v", "T", "t ", "ego.x", "x,y", "é", ""]),
                  st.text(max_size=6))
SETTINGS = settings(max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


def _read_or_one_line(read, path: Path):
    try:
        result = read(path)
    except SimcredError as exc:
        assert "\n" not in str(exc) and str(exc).strip()
        return None
    return result


@SETTINGS
@given(st.lists(NAMES, min_size=1, max_size=5), st.lists(st.lists(CELLS, min_size=0, max_size=6),
                                                          max_size=6), st.integers(1, 3))
def test_csv_directories(header, rows, files):
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        text = ",".join(header) + "\n" + "".join(",".join(r) + "\n" for r in rows)
        for k in range(files):
            (directory / f"run_{k}.csv").write_text(text, encoding="utf-8", errors="replace")
        traces = _read_or_one_line(TraceSet.read, directory)
        if traces is not None:  # what is read is a valid trace set
            assert np.isfinite(traces.values).all() and np.isfinite(traces.time).all()
            for lo, hi in zip(traces.offsets[:-1], traces.offsets[1:], strict=True):
                assert (np.diff(traces.time[lo:hi]) > 0).all()


@SETTINGS
@given(st.lists(st.one_of(st.text(max_size=3), st.integers(-3, 3)), min_size=1, max_size=12),
       st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=12, max_size=12),
       st.booleans())
def test_parquet_tables(runs, values, integer_runs):
    n = len(runs)
    labels = [r if isinstance(r, str) else str(r) for r in runs]
    column = pa.array([hash(r) % 5 for r in labels]) if integer_runs else pa.array(labels)
    table = pa.table({"run": column, "t": values[:n], "x": values[::-1][:n]})
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "set.parquet"
        pq.write_table(table, path)
        traces = _read_or_one_line(TraceSet.read, path)
        if traces is not None:
            assert np.isfinite(traces.values).all()


YAML_VALUES = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=True),
              st.text(max_size=12), st.sampled_from(["0 <= v <= 40", "v <= 100 km/h", "1e999",
                                                     "not not v", "(((v", "m/s", ".inf"])),
    lambda inner: st.one_of(st.lists(inner, max_size=3),
                            st.dictionaries(st.text(max_size=8), inner, max_size=3)),
    max_leaves=12)
LIBRARY_KEYS = ["variables", "components", "models", "architecture", "test_cases"]
VALIDATION_KEYS = ["name", "test_case", "reference", "candidates", "features", "conditions",
                   "comparison", "inputs", "pairs", "groups", "min_data", "segments"]


@SETTINGS
@given(st.dictionaries(st.sampled_from(LIBRARY_KEYS), YAML_VALUES, max_size=5))
def test_contract_libraries(document):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "lib.yaml"
        path.write_text(yaml.safe_dump(document, allow_unicode=True))
        _read_or_one_line(Library.read, path)


@SETTINGS
@given(st.dictionaries(st.sampled_from(VALIDATION_KEYS), YAML_VALUES, max_size=6))
def test_validation_files(document):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "validation.yaml"
        path.write_text(yaml.safe_dump(document, allow_unicode=True))
        _read_or_one_line(read_validation, path)
