"""The ``sc-rt`` command line: parse, call, print."""

from sc_rt.cli.main import main

__all__ = ["main"]
