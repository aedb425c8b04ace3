"""Load a sanitizer build of sc_rt._core in place of the installed one.

On PYTHONPATH (tests/test_sanitizers.py, `make check-sanitizers`) with
SCRT_SANITIZED_CORE=/path/to/_core.cpython-*.so: every Python process of the
run, the test's subprocesses too, imports that module as sc_rt._core. The
interpreter is not instrumented: the ASan runtime comes first through
LD_PRELOAD (tests/test_sanitizers.py sets it). Shadows the interpreter's own
sitecustomize, if any (Debian's only hooks apport)."""

import os
import sys

_path = os.environ.get("SCRT_SANITIZED_CORE")
if _path:
    import importlib.util

    import sc_rt  # lazy: does not import _core

    _spec = importlib.util.spec_from_file_location("sc_rt._core", _path)
    _mod = importlib.util.module_from_spec(_spec)
    sys.modules["sc_rt._core"] = _mod
    _spec.loader.exec_module(_mod)
    sc_rt._core = _mod
