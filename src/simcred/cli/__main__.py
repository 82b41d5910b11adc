"""``python -m simcred.cli``: the same as the ``simcred`` command."""

from simcred.cli import entry

entry()
