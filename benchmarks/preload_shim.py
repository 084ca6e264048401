"""Run a counting script again with a C interposer in ``LD_PRELOAD`` (a module).

``count_allocations.py`` and ``count_launches.py`` count calls into C libraries (``malloc``,
OpenCL's enqueue calls) by interposing them: :func:`rerun_with_shim` compiles the C source
with the system's C compiler into a temporary shared library and runs the calling script
again with it preloaded and ``flag`` set in the environment, which tells the script to
measure. Linux with glibc only.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path


def rerun_with_shim(source: str, name: str, flag: str, script: str, argv) -> int:
    """Compile ``source`` (C) as ``name.so``, run ``script`` with ``argv`` under it with the
    environment variable ``flag`` set; return its exit status."""
    with tempfile.TemporaryDirectory() as tmp:
        c_file, shim = Path(tmp) / f"{name}.c", Path(tmp) / f"{name}.so"
        c_file.write_text(source)
        subprocess.run(["cc", "-O2", "-shared", "-fPIC", str(c_file), "-o", str(shim), "-ldl"],
                       check=True)
        env = dict(os.environ, LD_PRELOAD=str(shim), **{flag: "1"})
        return subprocess.run([sys.executable, script, *argv], env=env).returncode
