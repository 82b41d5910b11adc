"""Typed names of the representations of one drive in the pipeline of [1] Fig. 1.

A representation is a measured trace (GT or SD), a resimulation of its description (rGT, rSD),
each with the ideal or the scenario-based sensor model ([sb], [1] §IV), or the fit of any of these
(fit(GT), fit(rSD[sb]), …). :class:`Rep` holds those parts as fields. It is also the ``str`` it
prints as — ``"fit(rGT[sb])"`` — so it is the key of the result dicts and of the JSON files (which
stay as they were) and ``result.reactions["GT"]`` still works; code asks the fields
(``rep.sensor``, ``rep.unfitted``), never slices the string.

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

import re
from enum import StrEnum

from simcred.errors import SimcredError

__all__ = ["GT", "SD", "Rep", "SensorKind", "Source"]


class Source(StrEnum):
    """What was measured: the ground truth (DGPS reference) or the AD function's sensor data."""

    GT = "GT"
    SD = "SD"


class SensorKind(StrEnum):
    """The sensor model of a resimulation."""

    IDEAL = "ideal"
    SCENARIO_BASED = "scenario-based"


SB = "[sb]"  # the suffix of a scenario-based representation's name (Rep prints it)
_SUFFIX = {SensorKind.IDEAL: "", SensorKind.SCENARIO_BASED: SB}
_PATTERN = re.compile(r"^(?P<fit>fit\()?(?P<r>r)?(?P<source>GT|SD)(?P<sb>\[sb\])?(?(fit)\))$")


class Rep(str):
    """One representation; equal to (and hashed as) its printed name.

    >>> key = Rep.of("GT", resimulated=True, sensor=SensorKind.SCENARIO_BASED).fit()
    >>> key, key.unfitted, key.sensor.value, key.unfitted.ideal()
    ('fit(rGT[sb])', 'rGT[sb]', 'scenario-based', 'rGT')
    """

    __slots__ = ("source", "resimulated", "sensor", "fitted")
    source: Source
    resimulated: bool
    sensor: SensorKind
    fitted: bool

    def __new__(cls, name: str) -> Rep:
        match = _PATTERN.match(str(name))
        if match is None:
            raise SimcredError(f"not a representation: {name!r} (e.g. GT, rSD, fit(rGT[sb]))")
        self = super().__new__(cls, name)
        self.source = Source(match["source"])
        self.resimulated = match["r"] is not None
        self.sensor = SensorKind.SCENARIO_BASED if match["sb"] else SensorKind.IDEAL
        self.fitted = match["fit"] is not None
        if self.sensor is SensorKind.SCENARIO_BASED and not self.resimulated:
            raise SimcredError(f"not a representation: {name!r} ([sb] only on a resimulation)")
        return self

    @classmethod
    def of(cls, source: Source | str, *, resimulated: bool = False,
           sensor: SensorKind = SensorKind.IDEAL, fitted: bool = False) -> Rep:
        name = f"{'r' if resimulated else ''}{Source(source).value}{_SUFFIX[SensorKind(sensor)]}"
        return cls(f"fit({name})" if fitted else name)

    def _with(self, **changes) -> Rep:
        parts = {"resimulated": self.resimulated, "sensor": self.sensor, "fitted": self.fitted}
        return Rep.of(self.source, **{**parts, **changes})

    def fit(self) -> Rep:
        """The fit of this representation: ``GT`` → ``fit(GT)``."""
        return self._with(fitted=True)

    @property
    def unfitted(self) -> Rep:
        """What was fitted: ``fit(rGT)`` → ``rGT`` (itself if not a fit)."""
        return self._with(fitted=False)

    def resimulation(self, sensor: SensorKind = SensorKind.IDEAL) -> Rep:
        """The resimulation of this measurement's description: ``GT`` → ``rGT`` / ``rGT[sb]``."""
        return Rep.of(self.source, resimulated=True, sensor=sensor)

    def ideal(self) -> Rep:
        """The same representation with the ideal sensor model: ``rGT[sb]`` → ``rGT``."""
        return self._with(sensor=SensorKind.IDEAL)

    @property
    def file_stem(self) -> str:
        """A file name for it: ``fit(rGT[sb])`` → ``fit_rGT_sb``."""
        sensor = "_sb" if self.scenario_based else ""
        return f"{'fit_' if self.fitted else ''}{'r' if self.resimulated else ''}" \
               f"{self.source.value}{sensor}"

    @property
    def scenario_based(self) -> bool:
        return self.sensor is SensorKind.SCENARIO_BASED

    def __reduce__(self):
        return Rep, (str(self),)


GT = Rep("GT")
SD = Rep("SD")
