"""Build the plant FMUs from source: generate, compile, zip; cached by a key over the sources.

A user never runs the compiler: :func:`fmu_path` returns a ready ``.fmu``, building it on first
use. The cache key is the SHA-256 of every input of the build (the model's variable table and C
sources, the shared FMI layer, this file, the generator, the compiler's identity and flags), so a
changed source can never load a stale binary.
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from fmus import modeldef
from fmus.errors import BuildError

HERE = Path(__file__).resolve().parent
COMMON = HERE / "common"
MODELS = ("turntable", "imu")
FMI_VERSIONS = (2, 3)
# the C files of fmus/common compiled into every FMU: its FMI version's layer, then the
# version-neutral half of the layers and the models' helpers
LAYER_SOURCES = {2: ["fmi2_layer.c"], 3: ["fmi3_layer.c", "fmi3_unsupported.c"]}
COMMON_SOURCES = ["fmi_common.c", "model_support.c"]

CFLAGS = ["-std=c11", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-Wshadow", "-Wpedantic",
          "-Werror", "-fvisibility=hidden",
          # no fused multiply-add contraction: the same seed gives the same bits on every CPU
          "-ffp-contract=off", "-fno-fast-math"]


def cache_dir() -> Path:
    root = os.environ.get("CALBENCH_CACHE")
    base = Path(root) if root else Path.home() / ".cache" / "calbench"
    return base / "fmus"


def _fmi_headers() -> Path:
    import fmpy

    path = Path(fmpy.__file__).parent / "c-code"
    if not (path / "fmi2Functions.h").exists():
        raise BuildError(f"FMI headers not found in {path} (fmpy installation incomplete)")
    return path


def _compiler() -> str:
    cc = os.environ.get("CC", "cc")
    if shutil.which(cc) is None:
        raise BuildError(f"no C compiler: {cc!r} not found on PATH (install gcc, or set CC)")
    return cc


def _compiler_identity(cc: str) -> str:
    out = subprocess.run([cc, "--version"], capture_output=True, text=True, check=False)
    return out.stdout.splitlines()[0] if out.stdout else cc


def _model_dir(model: str | Path) -> Path:
    """A built-in model by name, or any folder holding a ``variables.py`` (defining ``TABLE``)
    and the C sources it lists: the tests build their own small FMUs this way."""
    if isinstance(model, Path):
        if not (model / "variables.py").exists():
            raise ValueError(f"{model}: a model folder needs a variables.py defining TABLE")
        return model
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}: expected one of {MODELS} or a model folder")
    return HERE / model


def load_table(model: str | Path) -> modeldef.ModelTable:
    folder = _model_dir(model)
    if not isinstance(model, Path):
        return importlib.import_module(f"fmus.{model}.variables").TABLE
    spec = importlib.util.spec_from_file_location(f"_calbench_model_{folder.name}", folder / "variables.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.TABLE


def _model_sources(model: str | Path) -> list[Path]:
    """Every file of the model's folder that can change the FMU (without importing its table,
    which runs the servo design)."""
    folder = _model_dir(model)
    return sorted(p for p in folder.iterdir() if p.suffix in (".c", ".h", ".py"))


def _platform_dir(fmi_version: int) -> str:
    machine = platform.machine().lower()
    system = platform.system().lower()
    if system != "linux" and system != "darwin":
        raise BuildError(f"building on {system} is not supported")
    if fmi_version == 2:
        bits = "64" if sys.maxsize > 2**32 else "32"
        return {"linux": "linux", "darwin": "darwin"}[system] + bits
    arch = {"amd64": "x86_64", "arm64": "aarch64"}.get(machine, machine)
    return f"{arch}-{system}"


def _link_flags() -> list[str]:
    """A model spread over several C files can miss a definition; a shared library links with
    it undefined and fails only when a master loads it. GNU ld refuses it at build time with
    -z defs; Apple's linker does by default."""
    return [] if platform.system() == "Darwin" else ["-Wl,-z,defs"]


def _shared_suffix() -> str:
    return ".dylib" if platform.system() == "Darwin" else ".so"


def source_key(model: str | Path, fmi_version: int) -> str:
    """SHA-256 over everything that goes into the FMU."""
    cc = _compiler()
    h = hashlib.sha256()
    inputs = ([HERE / "modeldef.py", HERE / "build.py"]
              + sorted(COMMON.glob("*.[ch]")) + _model_sources(model))
    for p in inputs:
        h.update(p.name.encode())
        h.update(p.read_bytes())
    h.update(_compiler_identity(cc).encode())
    h.update(" ".join(CFLAGS + _link_flags()).encode())
    h.update(f"fmi{fmi_version}".encode())
    h.update(_platform_dir(fmi_version).encode())
    return h.hexdigest()


def fmu_path(model: str | Path, fmi_version: int = 2) -> Path:
    """Path of the up-to-date ``.fmu`` for *model*, built now if the cache lacks it."""
    return build_fmu(model, fmi_version, force=False)


def build_fmu(model: str | Path, fmi_version: int = 2, force: bool = False) -> Path:
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"fmi_version {fmi_version}: expected one of {FMI_VERSIONS}")
    folder = _model_dir(model)
    key = source_key(model, fmi_version)
    stem = f"calbench_{model}" if not isinstance(model, Path) else folder.name
    target = cache_dir() / f"{stem}-fmi{fmi_version}-{key[:16]}.fmu"
    if target.exists() and not force:
        return target
    table = load_table(model)
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent, prefix=".build-") as tmp:
        fmu = _build_into(Path(tmp), model, table, fmi_version, key)
        os.replace(fmu, target)  # atomic: concurrent builders never see half an FMU
    return target


def _build_into(work: Path, model: str | Path, table: modeldef.ModelTable, fmi_version: int,
                key: str) -> Path:
    cc = _compiler()
    src = work / "sources"
    src.mkdir()
    token = table.token(key)
    (src / "config.h").write_text(modeldef.c_header(table, token))
    folder = _model_dir(model)
    c_files = ([COMMON / n for n in LAYER_SOURCES[fmi_version] + COMMON_SOURCES]
               + [folder / s for s in table.sources])
    headers = sorted(COMMON.glob("*.h")) + sorted(folder.glob("*.h"))
    fmi_headers = sorted(_fmi_headers().glob(f"fmi{fmi_version}*.h"))
    for f in c_files + headers + fmi_headers:
        shutil.copy(f, src / f.name)
    c_names = [f.name for f in c_files]

    binary_name = table.identifier + _shared_suffix()
    plat = _platform_dir(fmi_version)
    bindir = work / "binaries" / plat
    bindir.mkdir(parents=True)
    cmd = [cc, *CFLAGS, f"-I{src}", "-o", str(bindir / binary_name),
           *[str(src / n) for n in c_names], "-lm", *_link_flags()]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise BuildError(f"building {table.identifier} (FMI {fmi_version}) failed:\n"
                         f"$ {' '.join(cmd)}\n{proc.stderr}")

    if fmi_version == 2:
        md = modeldef.model_description_fmi2(table, token, c_names)
    else:
        md = modeldef.model_description_fmi3(table, token)
    (work / "modelDescription.xml").write_text(md)
    (src / "buildDescription.xml").write_text(_build_description(table, c_names))

    fmu = work / f"{table.identifier}.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as z:
        # fixed timestamps: the archive depends only on its contents
        def add(path: Path, arc: str) -> None:
            info = zipfile.ZipInfo(arc, date_time=(2020, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            z.writestr(info, path.read_bytes())

        add(work / "modelDescription.xml", "modelDescription.xml")
        add(bindir / binary_name, f"binaries/{plat}/{binary_name}")
        for f in sorted(src.iterdir()):
            add(f, f"sources/{f.name}")
    return fmu


def _build_description(table: modeldef.ModelTable, c_names: list[str]) -> str:
    files = "\n".join(f'      <SourceFile name="{n}"/>' for n in c_names)
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<fmiBuildDescription fmiVersion="3.0">\n'
        f'  <BuildConfiguration modelIdentifier="{table.identifier}">\n'
        '    <SourceFileSet language="C99">\n'
        f"{files}\n"
        "    </SourceFileSet>\n"
        "  </BuildConfiguration>\n"
        "</fmiBuildDescription>\n"
    )


def build_all(force: bool = False, versions=FMI_VERSIONS) -> list[Path]:
    return [build_fmu(m, v, force=force) for m in MODELS for v in versions]
