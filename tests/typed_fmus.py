"""Build the hand-written test FMUs of tests/fmus/typed2 and typed3 (a model.c and its own
modelDescription.xml each, outside fmus/: the shared layers there offer Float64, Int32 and
Boolean only, and these models exist to exercise every FMI type).

The standard makes an FMU export every function of its version, and fmpy loads them all; a test
model writes only the ones it needs, and every other one is generated here from the FMI
headers' ``...TYPE`` typedefs as a stub that returns an error (or NULL)."""
from __future__ import annotations

import hashlib
import re
import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from fmus.build import _fmi_headers, _platform_dir, _shared_suffix

_TYPEDEF = re.compile(r"typedef\s+([\w\s\*]+?)\s*\b(fmi[23]\w+)TYPE\s*\(([^;]*?)\)\s*;", re.S)


def _stubs(fmi_version: int, defined: set[str]) -> str:
    header = (_fmi_headers() / f"fmi{fmi_version}FunctionTypes.h").read_text()
    out = [f'#include "fmi{fmi_version}Functions.h"']
    for ret, name, params in _TYPEDEF.findall(header):
        if name in defined:
            continue
        ret = " ".join(ret.split())
        if ret.endswith("Status"):
            body = f"return fmi{fmi_version}Error;"
        elif ret == "void":
            body = ""
        elif "char" in ret:
            body = 'return "";'
        else:  # an instance
            body = "return NULL;"
        out.append(f"{ret} {name}({' '.join(params.split())}) {{ {body} }}")
    return "\n".join(out) + "\n"


def build_test_fmu(folder: Path, out_dir: Path) -> Path:
    """The FMU of *folder* (model.c + modelDescription.xml), built into *out_dir* once per
    content (the file name carries a hash of the sources)."""
    md_text = (folder / "modelDescription.xml").read_text()
    source = (folder / "model.c").read_text()
    key = hashlib.sha256((md_text + source).encode()).hexdigest()[:12]
    root = ET.fromstring(md_text)
    version = int(root.get("fmiVersion")[0])
    ident = root.find("CoSimulation").get("modelIdentifier")
    fmu = out_dir / f"{ident}-{key}.fmu"
    if fmu.exists():
        return fmu
    work = out_dir / f"{ident}-{key}"
    work.mkdir(parents=True, exist_ok=True)
    inc = f"-I{_fmi_headers()}"
    obj = work / "model.o"
    subprocess.run(["cc", "-std=c11", "-O1", "-fPIC", "-Wall", "-Wextra", "-Werror", inc, "-c",
                    str(folder / "model.c"), "-o", str(obj)], check=True, capture_output=True, text=True)
    nm = subprocess.run(["nm", "-g", "--defined-only", str(obj)], check=True, capture_output=True,
                        text=True).stdout
    defined = {line.split()[-1] for line in nm.splitlines() if line.strip()}
    (work / "stubs.c").write_text(_stubs(version, defined))
    binary = work / (ident + _shared_suffix())
    # the stubs keep the headers' unnamed parameters: C2x allows them in a definition
    subprocess.run(["cc", "-std=c2x", "-fPIC", "-shared", "-w", inc, "-o", str(binary), str(obj),
                    str(work / "stubs.c"), "-lm"], check=True, capture_output=True, text=True)
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", md_text)
        z.write(binary, f"binaries/{_platform_dir(version)}/{binary.name}")
        z.writestr("sources/model.c", source)
    return fmu
