"""Reading an XML file with one-line errors (the XSD checks of the OpenSCENARIO and OpenDRIVE
files simcred writes)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from simcred.errors import SimcredError


def read_xml(path: Path) -> ET.ElementTree:
    """The parsed file; :class:`~simcred.errors.SimcredError` with one line naming the file
    when it cannot be read or is not well-formed."""
    try:
        return ET.parse(path)
    except OSError as exc:
        raise SimcredError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except ET.ParseError as exc:
        raise SimcredError(f"{path}: not well-formed XML: {exc}") from None
