"""sc-rt: real-time attitude-control emulator for a combined spacecraft with
four reaction wheels, some of them faulty.

The control laws live in the C++ core (``sc_rt._core``); this package holds
the plant, the scenario files, the offline simulator, the LCM emulator and
the command line (``sc-rt``).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("sc-rt")
except PackageNotFoundError:  # running from a source tree without install
    __version__ = "0+unknown"

__all__ = ["__version__"]
