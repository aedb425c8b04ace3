"""sc-rt: real-time attitude-control emulator for a combined spacecraft with
four reaction wheels, some of them faulty.

The control laws live in the C++ core (``sc_rt._core``); this package holds
the plant, the scenario files, the offline simulator, the LCM emulator and
the command line (``sc-rt``).
"""

import os
from importlib.metadata import PackageNotFoundError, version

# sc-rt's matrices are 3x3 and 3x4: BLAS worker threads never help, and their
# busy-waiting after a numpy call steals a core from the control loop on a
# 2-core bench. Takes effect when sc_rt is imported before numpy (the CLI);
# a user's own setting wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

try:
    __version__ = version("sc-rt")
except PackageNotFoundError:  # running from a source tree without install
    __version__ = "0+unknown"

__all__ = ["__version__"]
