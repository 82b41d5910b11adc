"""Safe XML access shared by the XML readers: no DTDs, no entity expansion, gzip transparent."""

from __future__ import annotations

import gzip
from pathlib import Path
from typing import BinaryIO

from defusedxml import DefusedXmlException
from defusedxml import ElementTree as SafeET

from simcred.errors import TraceSetError

#: what a malformed or hostile XML file raises while being parsed
XML_ERRORS = (SafeET.ParseError, DefusedXmlException, OSError, EOFError,
              LookupError, UnicodeError)  # an unknown or wrong declared encoding


def open_xml(path: Path) -> BinaryIO:
    """The file's bytes, decompressed when its name ends in ``.gz``."""
    return gzip.open(path, "rb") if path.name.lower().endswith(".gz") else open(path, "rb")


def iterparse(stream: BinaryIO, events: tuple[str, ...]):
    """``iterparse`` that refuses DTDs, entities and external references (defusedxml)."""
    return SafeET.iterparse(stream, events=events, forbid_dtd=True)


def unreadable(path: Path, exc: BaseException) -> TraceSetError:
    reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return TraceSetError(f"{path}: unreadable XML ({reason})")


def xml_root(path: Path) -> str:
    """The tag of the root element, read safely (see :func:`iterparse`)."""
    try:
        with open_xml(path) as stream:
            for _, element in iterparse(stream, ("start",)):
                return element.tag
    except XML_ERRORS as exc:
        raise unreadable(path, exc) from None
    raise TraceSetError(f"{path}: empty XML document")
