"""The native hot loop (span.c), compiled on first use and cached by the SHA-256 of its source.

The ctypes structures here mirror the C structs in span.c field for field; a run's units are
resolved into them by :mod:`orchestrator.native.plan`."""
from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

SOURCE = Path(__file__).with_name("span.c")

c_long_p = ctypes.POINTER(ctypes.c_long)
c_double_p = ctypes.POINTER(ctypes.c_double)
c_uint_p = ctypes.POINTER(ctypes.c_uint)
c_int_p = ctypes.POINTER(ctypes.c_int)


class UnitPlan(ctypes.Structure):
    _fields_ = [
        ("component", ctypes.c_void_p),
        ("do_step", ctypes.c_void_p), ("set_real", ctypes.c_void_p), ("get_real", ctypes.c_void_p),
        ("set_int", ctypes.c_void_p), ("get_int", ctypes.c_void_p), ("set_der", ctypes.c_void_p),
        ("multiple", ctypes.c_long),
        ("n_rin", ctypes.c_long), ("rin_vr", c_uint_p), ("rin_slot", c_long_p),
        ("rin_scale", c_double_p), ("rin_shift", c_double_p), ("rin_buf", c_double_p),
        ("n_iin", ctypes.c_long), ("iin_vr", c_uint_p), ("iin_slot", c_long_p), ("iin_buf", c_int_p),
        ("n_der", ctypes.c_long), ("der_vr", c_uint_p), ("der_slot", c_long_p),
        ("der_scale", c_double_p), ("der_order", c_int_p), ("der_buf", c_double_p),
        ("n_rout", ctypes.c_long), ("rout_vr", c_uint_p), ("rout_slot", c_long_p),
        ("rout_scale", c_double_p), ("rout_shift", c_double_p), ("rout_buf", c_double_p),
        ("n_iout", ctypes.c_long), ("iout_vr", c_uint_p), ("iout_slot", c_long_p), ("iout_buf", c_int_p),
    ]


class SpanError(ctypes.Structure):
    _fields_ = [("step", ctypes.c_long), ("unit", ctypes.c_long), ("call", ctypes.c_long),
                ("status", ctypes.c_long), ("index", ctypes.c_long), ("warned", ctypes.c_long)]


CALL_DO_STEP = 4  # span.c's CALL_DO_STEP
CALLS = {1: "fmi2SetReal", 2: "fmi2SetInteger", 3: "fmi2SetRealInputDerivatives",
         4: "fmi2DoStep", 5: "fmi2GetReal", 6: "fmi2GetInteger", 7: "non-finite output"}

_lib = None


def _cache() -> Path:
    root = os.environ.get("CALBENCH_CACHE")
    return (Path(root) if root else Path.home() / ".cache" / "calbench") / "native"


def compiled(source: Path, version: str = "v1") -> ctypes.CDLL:
    """*source* (one C file, C11, no dependencies but libm) compiled into the cache and loaded;
    the build is keyed by the SHA-256 of the source, so a changed source is always rebuilt."""
    src = source.read_bytes()
    key = hashlib.sha256(src + version.encode()).hexdigest()[:16]
    target = _cache() / f"{source.stem}-{key}.so"
    if not target.exists():
        cc = os.environ.get("CC", "cc")
        if shutil.which(cc) is None:
            raise RuntimeError(f"{source.name} needs a C compiler: {cc!r} not found")
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
            out = Path(tmp) / f"{source.stem}.so"
            cmd = [cc, "-std=c11", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-Werror",
                   "-fvisibility=hidden", "-o", str(out), str(source), "-lm"]
            proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
            if proc.returncode:
                raise RuntimeError(f"compiling {source} failed:\n{proc.stderr}")
            os.replace(out, target)
    return ctypes.CDLL(str(target))


def library() -> ctypes.CDLL:
    """The compiled span loop (built now if the cache lacks this source's build)."""
    global _lib
    if _lib is not None:
        return _lib
    lib = compiled(SOURCE)
    fn = lib.calbench_run_span
    fn.restype = ctypes.c_int
    fn.argtypes = [ctypes.POINTER(UnitPlan), ctypes.c_long, ctypes.c_long, c_double_p,
                   ctypes.c_double, ctypes.c_double, ctypes.c_long, ctypes.c_long, ctypes.c_int,
                   c_double_p, ctypes.c_long, c_long_p, ctypes.c_long, ctypes.c_long,
                   ctypes.c_long, ctypes.POINTER(SpanError)]
    _lib = lib
    return lib
