"""Loading Mitsuba 3 (an optional extra: ``pip install -e '.[pathtrace]'``) on a machine without a GPU.

The ``llvm_ad_rgb`` variant JIT-compiles its kernels with LLVM, which Dr.Jit looks up as
``libLLVM.so``; Debian ships it as ``libLLVM-19.so`` (package ``libllvm19``), so
``DRJIT_LIBLLVM_PATH`` must name the file (docs/pitfalls.md "Mitsuba 3").  :func:`load_mitsuba` sets it
when it is unset and a Debian ``libLLVM-*.so`` exists, imports ``mitsuba``, selects the variant, and
otherwise raises :class:`MitsubaUnavailable` with the line that installs what is missing.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

#: The Mitsuba variant: CPU (LLVM JIT), RGB rendering, differentiable build (the one PyPI ships for the CPU).
VARIANT = "llvm_ad_rgb"
#: Where Debian puts libLLVM-N.so (x86_64 and arm64).
LLVM_DIRS = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib")
#: The LLVM release preferred when several are installed (the one Dr.Jit 1.x is built and tested against).
PREFERRED_LLVM = 19
#: The install line printed when something is missing.
INSTALL_HINT = ("apt-get install --no-install-recommends libllvm19 && pip install -e '.[pathtrace]' "
                "(or `make hardcases`, which does both)")


class MitsubaUnavailable(RuntimeError):
    """Mitsuba 3 or the LLVM library its CPU variant needs is not installed; the message says how to install it."""


def find_libllvm(dirs=LLVM_DIRS) -> Path | None:
    """The newest Debian ``libLLVM-N.so`` (``PREFERRED_LLVM`` first) in ``dirs``, or None."""
    found = []
    for d in dirs:
        for p in Path(d).glob("libLLVM-*.so*") if Path(d).is_dir() else ():
            m = re.match(r"libLLVM-(\d+)", p.name)
            if m:
                found.append((int(m.group(1)) == PREFERRED_LLVM, int(m.group(1)), len(p.name), p))
    if not found:
        return None
    found.sort(key=lambda t: (t[0], t[1], -t[2]))
    return found[-1][3]


def load_mitsuba():
    """The ``mitsuba`` module with :data:`VARIANT` selected (MitsubaUnavailable otherwise)."""
    if not os.environ.get("DRJIT_LIBLLVM_PATH"):
        lib = find_libllvm()
        if lib is not None:
            os.environ["DRJIT_LIBLLVM_PATH"] = str(lib)
    try:
        import mitsuba as mi
    except ImportError as e:
        raise MitsubaUnavailable(f"mitsuba is not installed ({e}); install: {INSTALL_HINT}") from None
    if mi.variant() != VARIANT:
        try:
            mi.set_variant(VARIANT)
        except (ImportError, AttributeError, RuntimeError) as e:
            lib = os.environ.get("DRJIT_LIBLLVM_PATH", "unset")
            raise MitsubaUnavailable(f"mitsuba variant {VARIANT} cannot start (DRJIT_LIBLLVM_PATH={lib}: {e}); "
                                     f"install: {INSTALL_HINT}") from None
    return mi


def mitsuba_available() -> tuple[bool, str]:
    """(True, version) when :func:`load_mitsuba` works, else (False, the reason): for tests that skip."""
    try:
        mi = load_mitsuba()
    except MitsubaUnavailable as e:
        return False, str(e)
    return True, mi.__version__
