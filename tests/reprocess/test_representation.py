"""Typed representation keys: fields instead of string surgery, same names as before."""

import pickle

import pytest

from simcred.errors import SimcredError
from simcred.reprocess.representation import GT, SD, Rep, SensorKind, Source

NAMES = ["GT", "SD", "rGT", "rSD", "rGT[sb]", "rSD[sb]", "fit(GT)", "fit(SD)", "fit(rGT)",
         "fit(rSD)", "fit(rGT[sb])", "fit(rSD[sb])"]


@pytest.mark.parametrize("name", NAMES)
def test_a_name_round_trips_through_its_fields(name):
    key = Rep(name)
    assert key == name and hash(key) == hash(name) and str(key) == name
    rebuilt = Rep.of(key.source, resimulated=key.resimulated, sensor=key.sensor,
                     fitted=key.fitted)
    assert rebuilt == name
    assert pickle.loads(pickle.dumps(key)).sensor is key.sensor  # Dask ships keys


def test_fields_against_the_paper_names():
    key = Rep("fit(rSD[sb])")
    assert (key.source, key.resimulated, key.sensor, key.fitted) == (
        Source.SD, True, SensorKind.SCENARIO_BASED, True)
    assert key.unfitted == "rSD[sb]" and key.unfitted.ideal() == "rSD"
    assert GT.fit() == "fit(GT)" and SD.resimulation(SensorKind.SCENARIO_BASED) == "rSD[sb]"
    assert Rep("fit(rGT[sb])").file_stem == "fit_rGT_sb" and GT.file_stem == "GT"
    assert {Rep("rGT"): 1}["rGT"] == 1  # plain strings still find typed keys


@pytest.mark.parametrize("name", ["", "gt", "fit(GT", "GT[sb]", "fit(fit(GT))", "rXY"])
def test_anything_else_is_rejected(name):
    with pytest.raises(SimcredError, match="not a representation"):
        Rep(name)
