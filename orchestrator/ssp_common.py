"""SSP 1.0 archives (System Structure and Parameterization) as calbench reads and writes them:
the namespaces, the archive's layout and calbench's own annotations, shared by the reader
(:mod:`orchestrator.ssp_load`) and the writer (:mod:`orchestrator.ssp_save`) so that what one
writes the other reads back as the same :class:`~orchestrator.system.System`.

SSP has no communication step, no co-simulation algorithm and no notion of what to record.
calbench reads them from one annotation, anywhere in the SSD
(:func:`~orchestrator.ssp_save.save_ssp` puts it in ``ssd:DefaultExperiment``)::

    <ssc:Annotation type="org.calbench.system">
      <calbench step="0.005" algorithm="gauss-seidel" record="imu.gyro imu.acc"
                record_every="1" order="table imu">
        <aggregate signal="imu.gyro" how="sum"/>
        <unit name="imu" role="imu" step_multiple="1" role_options='{"gyro_output": "rate"}'>
          <map role="omega.x" name="AngularRate_X"/>
        </unit>
      </calbench>
    </ssc:Annotation>

Without it: ``step = 0.005`` s, Gauss–Seidel, every unit at the base step, no roles, and every
connected output is recorded (each connection's start connector, once). Roles, role options,
mappings and step multiples are calbench concepts and live only in that annotation; a
connection's ``derivative_order`` lives in a connection annotation
``<ssc:Annotation type="org.calbench.connection"><calbench derivative_order="1"/>``.

Names: SSP connectors and parameters name the FMU's own variables. Where a unit has a role with
a ``mapping`` (role name -> the FMU's name), :func:`~orchestrator.ssp_save.save_ssp` writes the
FMU's names and :func:`~orchestrator.ssp_load.load_ssp` maps them back to role names, so the
orchestrator applies the same role bindings (unit conversions) as for the TOML system. Vector
prefixes (``plate.omega``) are expanded to scalar connections on save.
"""
from __future__ import annotations

SSD_NS = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"
FMU_TYPE = "application/x-fmu-sharedlibrary"
SYSTEM_ANNOTATION = "org.calbench.system"
CONNECTION_ANNOTATION = "org.calbench.connection"
SSD_NAME = "SystemStructure.ssd"


def ssd(tag: str) -> str:
    return f"{{{SSD_NS}}}{tag}"


def ssv(tag: str) -> str:
    return f"{{{SSV_NS}}}{tag}"


def ssc(tag: str) -> str:
    return f"{{{SSC_NS}}}{tag}"
