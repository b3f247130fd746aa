"""The domain-free co-simulation engine: it steps FMUs and Python components on a fixed grid and
knows nothing of IMUs (roles, FMU schemes and components are registered from outside).

Modules, each importing only modules listed before it (so there is no import circle):

* the base, importing at most ``errors`` and ``plugins``: ``errors`` (every exception, one base
  class), ``plugins`` (roles and FMU schemes other packages contribute, by entry point),
  ``fmu_resolver``, ``tomlfile``, ``si``, ``fmi_types`` (types,
  lossless connections, value checks, Parquet types), ``component`` (the Python component API),
  ``recording``, ``ssp_common``, ``native`` (the C span loop and its build),
  ``component_import`` (a ``module:Class`` found beside the system file, then on the path),
  ``sources`` (built-in signal sources: constant, step, ramp, sine, CSV table)
* the model: ``system`` (System, TOML layout), ``units`` (the Unit interface)
* units: ``fmu_units`` (FMI 2.0 / 3.0 through fmpy), ``component_unit``
* binding: ``roles``, ``wiring``, ``start_values`` (what a master may set before
  initialisation), ``record_select`` (``record.signals`` patterns), ``exchange`` (the run's
  typed slots)
* system files: ``ssp_load``, ``ssp_save``, ``loader`` (``load_system``: TOML or SSP by suffix)
* running: ``native.plan`` (FMI 2 units resolved for the C loop), ``loop_solver`` (algebraic
  loops solved at every step by fixed-point iteration), ``run_provenance`` (what produced a
  recording), ``master`` (Simulation, ``simulate``)
* checking: ``check`` (``check-fmu``), ``libcosim`` (the independent engine), ``verify``
"""
