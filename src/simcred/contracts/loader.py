"""Reading a library file safely: UTF-8 only, bounded size and nesting, no duplicate keys, no
aliases.

PyYAML's ``safe_load`` silently keeps the last of two equal keys (a second model of the same name
replaces the first), expands aliases (a few lines can stand for gigabytes: "billion laughs") and
recurses once per nesting level (10,000 nested lists overflow the stack). :class:`StrictLoader`
refuses all three with the line and column of the culprit.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from yaml.constructor import ConstructorError

from simcred.errors import SimcredError
from simcred.io._paths import check_regular

MAX_BYTES = 1_000_000  # a library is kilobytes; beyond this is a mistake, not a library
MAX_NESTING = 32


class LibraryError(SimcredError):
    """A malformed or inconsistent library; the message names the file and the entry."""


class StrictLoader(yaml.SafeLoader):
    """A SafeLoader that refuses duplicate keys, aliases and nesting beyond ``MAX_NESTING``."""

    def __init__(self, stream) -> None:
        super().__init__(stream)
        self._nesting = 0

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise ConstructorError(None, None, f"alias '*{event.anchor}' (aliases and anchors "
                                   "are not allowed in a library)", event.start_mark)
        self._nesting += 1
        if self._nesting > MAX_NESTING:
            raise ConstructorError(None, None, f"nested more than {MAX_NESTING} levels deep",
                                   self.peek_event().start_mark)
        try:
            return super().compose_node(parent, index)
        finally:
            self._nesting -= 1

    def construct_mapping(self, node, deep=False):
        seen: dict = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                duplicate = key in seen
            except TypeError:  # an unhashable key (a list or a mapping)
                raise ConstructorError(None, None, "a key must be a name, not a list or mapping",
                                       key_node.start_mark) from None
            if duplicate:
                raise ConstructorError(None, None, f"duplicate key '{key}' (first at line "
                                       f"{seen[key].line + 1})", key_node.start_mark)
            seen[key] = key_node.start_mark
        return super().construct_mapping(node, deep=deep)


def load_yaml(path: Path):
    """The data of the YAML file ``path``; a one-line :class:`LibraryError` naming the file and
    the line and column of the problem otherwise. Only a regular file is read (a FIFO or a
    device such as /dev/zero could block or never end: one line instead)."""
    check_regular(path)
    try:
        if path.stat().st_size > MAX_BYTES:
            raise LibraryError(f"{path}: {path.stat().st_size:,} bytes (a library has at most "
                               f"{MAX_BYTES:,})")
        raw = path.read_bytes()
    except OSError as exc:
        raise LibraryError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise LibraryError(f"{path}: line {line}: not UTF-8 (byte 0x{raw[exc.start]:02x} at "
                           f"offset {exc.start})") from None
    try:
        return yaml.load(text, Loader=StrictLoader)  # noqa: S506 (StrictLoader is a SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or "malformed YAML"
        raise LibraryError(f"{path}: {where}{problem}") from None
    except RecursionError:
        raise LibraryError(f"{path}: nested too deeply") from None
