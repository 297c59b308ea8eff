"""The ``jmeshtex`` command line: thin subcommands over the library API."""

from ._main import main as main
