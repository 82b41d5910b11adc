"""The ASAM Quality Checker for OpenSCENARIO XML (asam-qc-openscenarioxml, in the test extra),
run as its command line documents: a configuration XML naming the input file and the result
file, then the .xqar read back."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest


def quality_check(xosc: Path, tmp_path: Path) -> list[tuple[str, str, str]]:
    """(checker, status, issue level) for every checker (level "") and every issue it found."""
    pytest.importorskip("qc_openscenario", reason="asam-qc-openscenarioxml (the test extra)")
    from qc_baselib import Result

    report = tmp_path / "xosc.xqar"
    config = tmp_path / "qc.xml"
    config.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n<Config>\n'
        f'  <Param name="InputFile" value="{xosc}"/>\n'
        '  <CheckerBundle application="xoscBundle">\n'
        f'    <Param name="resultFile" value="{report}"/>\n'
        '  </CheckerBundle>\n</Config>\n')
    subprocess.run([sys.executable, "-m", "qc_openscenario", "-c", str(config)], check=True,
                   capture_output=True, cwd=tmp_path, timeout=120)
    result = Result()
    result.load_from_file(str(report))
    rows = []
    for bundle in result.get_checker_bundle_results():
        for checker in bundle.checkers:
            rows.append((checker.checker_id, checker.status.name, ""))
            rows += [(checker.checker_id, checker.status.name, issue.level.name)
                     for issue in checker.issues]
    return rows


#: The checker that needs a RoadNetwork (it resolves traffic-signal ids in it): skipped where
#: the scene has no road file (the A9 recording).
NEEDS_ROAD = "check_asam_xosc_reference_control_resolvable_signal_id_in_traffic_signal_state_action"


def assert_accepted(rows: list[tuple[str, str, str]], road: bool = True) -> None:
    """Every checker ran (none crashed; none skipped but, without a ``road`` file, the one that
    needs it), the schema check among them, and no issue of level ERROR."""
    checkers = {c for c, _, _ in rows}
    assert len(checkers) >= 17 and "check_asam_xosc_xml_valid_schema" in checkers
    skipped = {c for c, s, _ in rows if s != "COMPLETED"}
    assert skipped == (set() if road else {NEEDS_ROAD}), skipped
    assert [r for r in rows if r[2] == "ERROR"] == []
