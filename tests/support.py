"""Small test-side driver for one FMU through fmpy (independent of the orchestrator)."""
from __future__ import annotations

import ctypes
import shutil
import tempfile
import weakref
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)
from fmpy.fmi3 import (
    FMU3Slave,
    fmi3LogMessageCallback,  # noqa: F401  (documents the FMI 3 signature)
)


class Slave:
    """Instantiate an FMU, set start values by name, step it, read variables by name.

    ``log`` collects (status, message) pairs from the FMU's logger, so tests can check the
    message that names a bad parameter."""

    def __init__(self, fmu: str | Path, start: dict | None = None, name: str = "unit",
                 t0: float = 0.0, initialize: bool = True):
        self.md = read_model_description(str(fmu))
        self.fmi3 = self.md.fmiVersion.startswith("3")
        self._dir = extract(str(fmu), unzipdir=tempfile.mkdtemp(prefix="calbench-test-"))
        # a test that never calls close() (one that expects an error) still leaves no folder
        weakref.finalize(self, shutil.rmtree, self._dir, True)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.log: list[tuple[int, str]] = []
        cls = FMU3Slave if self.fmi3 else FMU2Slave
        self.fmu = cls(guid=self.md.guid, unzipDirectory=self._dir,
                       modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        logger = self._logger
        if self.fmi3:
            self.fmu.instantiate(loggingOn=False, logMessage=logger)
            self.fmu.enterInitializationMode(startTime=t0)
        else:
            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(logger)
            libc = ctypes.CDLL(None)
            libc.calloc.restype = ctypes.c_void_p
            cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(lambda n, s: libc.calloc(n, s))
            cb.freeMemory = fmi2CallbackFreeMemoryTYPE(lambda p: libc.free(ctypes.c_void_p(p)))
            self._callbacks = cb  # keep alive
            self.fmu.instantiate(loggingOn=False, callbacks=cb)
            self.fmu.setupExperiment(startTime=t0)
            self.fmu.enterInitializationMode()
        self.time = t0
        if start:
            self.set(start)
        if initialize:
            self.fmu.exitInitializationMode()

    def _logger(self, *args):
        # fmpy passes (env, instanceName, status, category, message) for FMI 2 and
        # (env, status, category, message) for FMI 3
        status, message = args[-3], args[-1]
        self.log.append((int(status), message.decode() if isinstance(message, bytes) else message))

    def vr(self, name: str) -> int:
        return self.vars[name].valueReference

    def set(self, values: dict) -> None:
        for name, value in values.items():
            v = self.vars[name]
            if v.type in ("Real", "Float64"):
                (self.fmu.setFloat64 if self.fmi3 else self.fmu.setReal)([v.valueReference], [float(value)])
            else:
                (self.fmu.setInt32 if self.fmi3 else self.fmu.setInteger)([v.valueReference], [int(value)])

    def get(self, *names: str) -> np.ndarray:
        out = []
        for name in names:
            v = self.vars[name]
            if v.type in ("Real", "Float64"):
                out.append((self.fmu.getFloat64 if self.fmi3 else self.fmu.getReal)([v.valueReference])[0])
            else:
                out.append((self.fmu.getInt32 if self.fmi3 else self.fmu.getInteger)([v.valueReference])[0])
        return np.array(out, dtype=float)

    def step(self, h: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        self.time += h

    def close(self) -> None:
        try:
            self.fmu.terminate()
        finally:
            self.fmu.freeInstance()
            shutil.rmtree(self._dir, ignore_errors=True)
