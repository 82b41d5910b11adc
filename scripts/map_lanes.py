"""The map's lanes vs the configured 3.5 m lanes on the shipped real CommonRoad scenes.

Every obstacle of tests/data/commonroad-ngsim and tests/data/commonroad-crime-ngsim as the TO
(its follower the EGO), reprocessed twice in the same run with the CLI's AD parameters from the
recorded EGO: ``lanes="configuration"`` (the geometry before the map's lanes) and
``lanes="map"``. Prints the map widths per scene, the number of lanes the AD function gets,
and how many reactions and maximum risks change (docs/reprocess.md, "The map's lanes").

    PYTHONPATH=src python scripts/map_lanes.py [lanelet|ego]
"""

from __future__ import annotations

import math
import statistics
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from simcred.reprocess.inputs import commonroad_drive, commonroad_obstacles
from simcred.reprocess.pipeline import ReprocessConfig, reprocess

DATA = Path(__file__).parents[1] / "tests" / "data"
SCENES = [*sorted((DATA / "commonroad-ngsim").glob("*.xml")),
          *sorted((DATA / "commonroad-crime-ngsim").glob("*.xml"))]


def _log(r: float) -> float:
    return math.log10(max(r, 1e-9))


def _stay(result) -> float | None:
    """Largest distance of the resimulated EGO from a recorded EGO that does not react."""
    if result.reactions["SD"].manoeuvre != "none":
        return None
    a, b = result.states["SD"]["ego"], result.states["rSD"]["ego"]
    return float(np.hypot(a.x - b.x, a.y - b.y).max())


def main(frame: str) -> None:
    widths: dict[str, list[float]] = {}
    count, lanes, changes, deltas, stays = Counter(), Counter(), Counter(), [], {}
    for path in SCENES:
        _, ids = commonroad_obstacles(path)
        for obstacle in ids:
            drive = commonroad_drive(path, obstacle, frame=frame)
            runs = {how: reprocess(drive, ReprocessConfig(from_recording=("set_speed", "lanes"),
                                                          lanes=how))
                    for how in ("configuration", "map")}
            ad = runs["map"].ad_function
            count[ad["from"]["lanes"]] += 1
            widths.setdefault(path.stem, []).append(ad["lane_width"])
            lanes[len(ad["lane_centres"])] += 1
            for rep, before in runs["configuration"].reactions.items():
                after = runs["map"].reactions[rep]
                if before.manoeuvre != after.manoeuvre:
                    changes[(rep, before.manoeuvre, after.manoeuvre,
                             "measurable" if after.measurable else "at the start")] += 1
            for rep, before in runs["configuration"].risk.items():
                after = runs["map"].risk[rep].max_risk
                deltas.append((abs(_log(after) - _log(before.max_risk)), rep,
                               f"{path.stem}/{obstacle}", before.max_risk, after))
            for how, result in runs.items():
                stays.setdefault(how, []).append(_stay(result))
    print(f"{frame} frame, {sum(count.values())} obstacles, lanes from {dict(count)}")
    for scene, w in widths.items():
        print(f"  {scene}: width median {statistics.median(w):.2f} m, "
              f"{min(w):.2f}-{max(w):.2f} m over {len(w)} EGOs")
    print(f"AD function lanes (EGO's + left neighbours): {dict(sorted(lanes.items()))}")
    print(f"reactions changed: {sum(changes.values())} of {len(deltas)}: "
          f"{dict(changes)}")
    changed = [d for d in deltas if d[0] > 1e-9]
    print(f"max risks changed: {len(changed)} of {len(deltas)} "
          f"({dict(Counter(d[1] for d in changed))}), > 0.1 decades: "
          f"{sum(d[0] > 0.1 for d in deltas)}")
    for d in sorted(deltas, reverse=True)[:5]:
        print(f"  {d[2]} {d[1]}: {d[3]:.3g} -> {d[4]:.3g}")
    for how, values in stays.items():
        kept = sorted(v for v in values if v is not None)
        print(f"{how}: {len(kept)} recorded EGOs do not react; resimulated within "
              f"{statistics.median(kept):.2f} m (median), {kept[-1]:.2f} m (max)")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "lanelet")
