"""Virtual try-on service: measurements -> body; mesh file -> garment model; body + model -> drape.

Stages (one sub-package each, data flows one way): ``body`` -> ``garment`` -> ``sim`` -> ``api``;
``cli`` is a thin command line over the same functions.
"""

import hashlib
import os
import shutil
import time
from pathlib import Path

__version__ = "0.1.0"

# s: kernel caches of other versions of the sources older than this are removed
STALE_CACHE_AGE = 7 * 24 * 3600.0


def _kernel_cache_dir() -> None:
    """Point numba's on-disk kernel cache (``cache=True``) at a directory named after a hash of this
    package's sources, before any kernel is compiled.

    Numba invalidates a cached kernel when its own file changes, not when a kernel it calls in another
    file does (a documented limit of its cache): after an edit of ``sweep_downward`` (sim/constraints.py),
    ``finish_step`` (sim/substeps.py) kept running the old one. Here any edit of the sources starts a
    fresh cache. A ``NUMBA_CACHE_DIR`` set by the environment (the Docker image) is kept; so is numba's own
    default if the user's cache directory cannot be written."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "tryon-kernels"
    here = base / digest.hexdigest()[:16]
    try:
        here.mkdir(parents=True, exist_ok=True)
    except OSError:
        return
    os.environ["NUMBA_CACHE_DIR"] = str(here)
    now = time.time()
    for other in base.iterdir():
        try:
            if other != here and now - other.stat().st_mtime > STALE_CACHE_AGE:
                shutil.rmtree(other, ignore_errors=True)
        except OSError:
            pass


_kernel_cache_dir()
