"""Bad input to the contracts CLI: every case exits 2 with one line on stderr that names the file
and the key (or the option), within 5 s, without a traceback (issue 15, item 7).

Each case is a library (a mutation of examples/contracts/figure2.yaml, or raw text/bytes) and a
command line; a watchdog (SIGALRM) fails a case that takes more than 5 s instead of hanging.
"""

from __future__ import annotations

import copy
import signal
from pathlib import Path

import pytest
import yaml

from simcred.cli import run

FIGURE2 = Path(__file__).resolve().parents[2] / "examples" / "contracts" / "figure2.yaml"
BASE = yaml.safe_load(FIGURE2.read_text())
WATCHDOG_S = 5


def model(name, **changes):
    def mutate(s):
        s["models"][name].update(changes)
    return mutate


def contract(name, **changes):
    def mutate(s):
        s["models"][name]["contract"].update(changes)
    return mutate


def tc(**changes):
    def mutate(s):
        s["test_cases"]["C_tc"].update(changes)
    return mutate


def nested_list(depth):
    return "variables:\n  v: " + "[" * depth + "1" + "]" * depth + "\n"


def duplicate_model() -> str:
    text = FIGURE2.read_text()
    return text.replace("  M2b:\n", "  M2a:\n")


def setdefault(key, value):
    def mutate(s):
        s[key] = value
    return mutate


def add_variable(name, spec):
    def mutate(s):
        s["variables"][name] = spec
    return mutate


def component(name, **changes):
    def mutate(s):
        s["components"][name].update(changes)
    return mutate


def with_flag(assumption):
    """A bool input 'flag' of I2 and an assumption of M2a that uses it."""
    def mutate(s):
        s["variables"]["flag"] = {"type": "bool"}
        s["components"]["I2"]["inputs"] = ["q", "flag"]
        s["models"]["M2a"]["contract"]["assumption"] = assumption
    return mutate


# (id, library: mutation of BASE | str | bytes, expected fragment, extra CLI arguments)
CASES = [
    ("non-utf8", b"variables:\n  v: {unit: \xff\xfe}\n", "not UTF-8", None),
    ("latin1", "variables:\n  v\u00e9: real\n".encode("latin-1"), "not UTF-8", None),
    ("cost-inf", model("M1", cost=float("inf")), "models.M1.cost", None),
    ("cost-1e400", "COST:1e400", "models.M1.cost", None),
    ("cost-nan", model("M1", cost=float("nan")), "models.M1.cost", None),
    ("cost-negative", model("M1", cost=-1), "models.M1.cost", None),
    ("cost-text", model("M1", cost="cheap"), "models.M1.cost", None),
    ("cost-huge", model("M1", cost=1e13), "models.M1.cost", None),
    ("cost-bool", model("M1", cost=True), "models.M1.cost", None),
    ("division-by-zero-term", contract("M2a", guarantee="err <= q / (q - q) * 1 m"), "division by",
     None),
    ("division-by-variable", contract("M2a", guarantee="err <= 1 m^2 / q"), "division by",
     None),
    ("division-by-zero", contract("M2a", guarantee="err <= q / 0"), "division by zero", None),
    ("500-not", contract("M2a", guarantee="not " * 500 + "err <= 1"), "nests more than", None),
    ("600-sum", contract("M2a", guarantee=" + ".join(["err"] * 600) + " <= 1"),
     "nests more than", None),
    ("300-abs", contract("M2a", guarantee="abs(" * 300 + "err" + ")" * 300 + " <= 1"),
     "nests more than", None),
    ("300-min", contract("M2a", guarantee="min(1, " * 300 + "err" + ")" * 300 + " <= 1"),
     "nests more than", None),
    ("10000-deep-list", nested_list(10_000), "nested more than", None),
    ("1e5000", contract("M2a", guarantee="err <= 1e5000"), "exponent", None),
    ("1e999999999", contract("M2a", guarantee="err <= 1e999999999"), "exponent", None),
    ("1e-999999999", contract("M2a", guarantee="err <= 1e-999999999"), "exponent", None),
    ("60-digits", contract("M2a", guarantee="err <= " + "7" * 60), "digits", None),
    ("power-tower", contract("M2a", guarantee="((err^16)^16)^16 <= 1"), "degree", None),
    ("power-17", contract("M2a", guarantee="err ^ 17 <= 1"), "exponent of ^", None),
    ("power-fraction", contract("M2a", guarantee="err ^ 0.5 <= 1"), "exponent of ^", None),
    ("huge-or-file", "BIG-OR", "bytes", None),
    ("long-or", contract("M2a", guarantee=" or ".join(["err <= 1"] * 2000)), "characters",
     None),
    ("bool-in-arithmetic", with_flag("flag + 1 <= 2"), "needs a number", None),
    ("bool-compared", with_flag("flag <= 1"), "needs a number", None),
    ("number-as-condition", contract("M2a", assumption="q + 1"), "not a condition", None),
    ("duplicate-model", duplicate_model(), "duplicate key 'M2a'", None),
    ("alias", FIGURE2.read_text().replace("cost: 5", "cost: &c 5").replace("cost: 2", "cost: *c"),
     "alias", None),
    ("extra-field", model("M1", colour="red"), "models.M1.colour", None),
    ("extra-top-level", setdefault("parameters_typo", {}), "parameters_typo", None),
    ("undeclared", contract("M1", assumption="0 <= w <= 4"), "undeclared variable 'w'", None),
    ("port-unit", component("I2", inputs=[{"q": "km"}]), "unit mismatch", None),
    ("two-drivers", component("I2", inputs=["v"], outputs=["err", "q"]), "driven by two",
     None),
    ("in-and-out", component("I2", outputs=["err", "q"]), "both an input and an output", None),
    ("syntax", contract("M2a", guarantee="err <= "), "models.M2a.contract", None),
    ("unknown-char", contract("M2a", guarantee="err <= 1 $ 2"), "models.M2a.contract", None),
    ("empty-assertion", contract("M2a", guarantee="  "), "empty assertion", None),
    ("assertion-list", contract("M2a", guarantee=["err <= 1"]), "models.M2a.contract", None),
    ("unknown-component", model("M1", implements="I9"), "unknown component 'I9'", None),
    ("missing-implements", lambda s: s["models"]["M1"].pop("implements"),
     "models.M1.implements", None),
    ("architecture-unknown", setdefault("architecture", ["I1", "I7"]), "architecture", None),
    ("architecture-twice", setdefault("architecture", ["I1", "I2", "I1"]), "listed twice", None),
    ("bad-unit", add_variable("z", {"unit": "blorbs per glorp"}), "not a physical unit", None),
    ("long-unit", add_variable("z", {"unit": "m" * 200}), "variables.z.unit", None),
    ("bad-name", add_variable("x y", {"unit": "m"}), "not a valid variable name", None),
    ("keyword-name", add_variable("and", {"unit": "m"}), "not a valid variable name", None),
    ("bad-type", add_variable("z", {"type": "complex"}), "variables.z.type", None),
    ("false-certificate", contract("M1", guarantee="0 <= q <= 50 and err <= 0.01"),
     "'err' is not a port of component 'I1'", None),
    ("assumes-output", contract("M2a", assumption="0 <= q <= 60 and err <= 1"),
     "'err' is not a port", None),
    ("test-case-assumes-driven", tc(assumption="10 <= v <= 30 and q <= 3"),
     "test_cases.C_tc.assumption", None),
    ("test-case-unknown-port", lambda s: (s["variables"].update(z={"unit": "m"}),
                                          s["test_cases"]["C_tc"].update(guarantee="z <= 1")),
     "test_cases.C_tc.guarantee", None),
    ("vacuous-model", contract("M2a", assumption="q >= 5 and q <= 1"), "unsatisfiable", None),
    ("vacuous-nonlinear", contract("M2a", assumption="q * q < 0"), "unsatisfiable", None),
    ("vacuous-test-case", tc(assumption="v > 3 and v < 3"), "unsatisfiable", None),
    ("no-contract", lambda s: s["models"]["M1"].pop("contract"), "models.M1.contract", None),
    ("contract-empty-list", model("M1", contract=[]), "at least one contract", None),
    ("division-by-constant-zero", contract("M2a", guarantee="err <= q / (2 - 2)"),
     "division by zero", None),
    ("division-by-decimal-zero", contract("M2a", guarantee="err <= q / (0.1 + 0.2 - 0.3)"),
     "division by zero", None),
    ("variable-named-t", lambda s: (s["variables"].update(t={"unit": "s"}),
                                    s["components"]["I2"]["inputs"].append("t")),
     "time column", None),
    ("contract-word", model("M1", contract="nonsense"), "models.M1.contract", None),
    ("name-reused", lambda s: s["test_cases"].update(M1={"assumption": "v <= 1"}),
     "also used in models", None),
    ("port-two-keys", component("I2", inputs=[{"q": "m", "v": "m/s"}]), "one 'name: unit'",
     None),
    ("unit-literal-mismatch", contract("M2a", guarantee="err <= 1 lux"), "unlike dimensions",
     None),
    ("sum-unlike", contract("M2a", guarantee="err + q * 1 s <= 1"), "unlike dimensions", None),
    ("unknown-unit-literal", contract("M2a", guarantee="err <= 3 blorbs"),
     "not a physical unit", None),
    ("offset-unit", lambda s: (s["variables"].update(T={"unit": "degC"}),
                               s["components"]["I2"]["inputs"].append("T"),
                               s["models"]["M2a"]["contract"].update(
                                   assumption="0 <= q <= 60 and T + 1 degF <= 30")),
     "cannot convert", None),
    ("abs-two-args", contract("M2a", guarantee="abs(err, q) <= 1"), "abs takes 1", None),
    ("top-level-list", "- 1\n- 2\n", "a library is a mapping", None),
    ("empty-file", "", "a library is a mapping", None),
    ("malformed-yaml", "variables:\n  v: {type: real\nmodels: [\n", "line", None),
    ("tab-indent", "variables:\n\tv: real\n", "line", None),
    ("unhashable-key", "variables:\n  ? [a, b]\n  : real\n", "a key must be a name", None),
    ("variables-list", setdefault("variables", ["v", "q"]), "variables", None),
    ("unknown-test-case", None, "no test case named 'nope'", ["configure", "--test-case",
                                                              "nope"]),
    ("bad-given", None, "--given", ["quotient", "--test-case", "C_tc", "--given", "I1"]),
    ("given-wrong-model", None, "not a model of component", ["quotient", "--test-case", "C_tc",
                                                             "--given", "I1=M2a"]),
    ("timeout-zero", None, "--timeout-ms", ["refines", "--refining", "M1", "--refined", "M1",
                                            "--timeout-ms", "0"]),
    ("unknown-contract", None, "no contract, model or test case named", [
        "refines", "--refining", "M9", "--refined", "M1"]),
]


def _library(tmp_path: Path, library) -> Path:
    path = tmp_path / "lib.yaml"
    if library is None:
        path.write_text(FIGURE2.read_text())
    elif library == "COST:1e400":
        path.write_text(FIGURE2.read_text().replace("cost: 1", "cost: 1e400", 1))
    elif library == "BIG-OR":  # a 10^6-term or (10 MB)
        huge = " or ".join(["err <= 1"] * 10**6)
        path.write_text(FIGURE2.read_text().replace('guarantee: "err <= 0.1"}',
                                                    f'guarantee: "{huge}"}}', 1))
    elif isinstance(library, bytes):
        path.write_bytes(library)
    elif isinstance(library, str):
        path.write_text(library)
    else:
        spec = copy.deepcopy(BASE)
        library(spec)
        path.write_text(yaml.safe_dump(spec, allow_unicode=True, width=10**9))
    return path


def _alarm(signum, frame):
    raise TimeoutError(f"no answer within {WATCHDOG_S} s")


def test_there_are_at_least_60_cases():
    assert len(CASES) >= 60
    assert len({c[0] for c in CASES}) == len(CASES)


@pytest.mark.parametrize(("library", "expected", "command"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_within_5_s(library, expected, command, tmp_path, capsys):
    path = _library(tmp_path, library)
    argv = ["contracts", "check", str(path)] if command is None else \
        ["contracts", command[0], str(path), *command[1:]]
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(WATCHDOG_S)
    try:
        code = run(argv)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert expected in err, err
    if command is None or command[0] == "configure":
        assert "lib.yaml" in err, err


def test_monitor_setup_names_a_model_of_another_component(tmp_path, capsys):
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "r0.csv").write_text("t,v,q,err\n0,1,1,0\n0.1,1,1,0\n")
    assert run(["monitor", str(FIGURE2), str(runs), "--setup", "I2=M1"]) == 2
    err = capsys.readouterr().err
    assert "'M1' is not a model of component 'I2'" in err and err.count("\n") == 1


def test_monitor_setup_with_two_models_of_one_component(tmp_path, capsys):
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "r0.csv").write_text("t,v,q,err\n0,1,1,0\n0.1,1,1,0\n")
    assert run(["monitor", str(FIGURE2), str(runs), "--setup", "I1=M1,I2=M2a,I2=M2b"]) == 2
    err = capsys.readouterr().err
    assert "component 'I2' has two models" in err and err.count("\n") == 1


@pytest.mark.parametrize("special", ["fifo", "/dev/zero", "/dev/null"])
def test_a_library_read_through_the_api_must_be_a_regular_file(special, tmp_path):
    """Library.read (not only the CLI's argument check) refuses special files in one line,
    before reading: a FIFO without a writer would block, /dev/zero never ends (issue 28)."""
    import os

    from simcred.contracts.library import Library
    from simcred.errors import SimcredError

    path = tmp_path / "lib.yaml"
    if special == "fifo":
        os.mkfifo(path)
    else:
        path = Path(special)
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(WATCHDOG_S)
    try:
        with pytest.raises(SimcredError, match="not a regular file") as caught:
            Library.read(path)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert len(str(caught.value).splitlines()) == 1 and str(path) in str(caught.value)
