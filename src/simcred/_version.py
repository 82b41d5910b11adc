"""simcred's version (from the installed distribution's metadata)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("simcred")
except PackageNotFoundError:  # pragma: no cover - running from a source tree without install
    __version__ = "0+unknown"


def versions(*packages: str, **programs: str) -> dict[str, str]:
    """What produced an output: simcred's version, then ``programs`` (name → version of a tool
    that is not a Python distribution, e.g. SUMO), then each installed distribution of
    ``packages`` ("not installed" if absent), then Python's."""
    import platform

    found = {"simcred": __version__, **programs}
    for name in packages:
        try:
            found[name] = version(name)
        except PackageNotFoundError:
            found[name] = "not installed"
    return {**found, "python": platform.python_version()}
