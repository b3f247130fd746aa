"""Every FMI 2 and FMI 3 type through the orchestrator (#20): read, set, connected, recorded with
its own Parquet type; arrays; an FMU that ends the run; start values of states; what a master
may not set or connect. The FMUs are tests/fmus/typed2 and typed3 (see their model.c for the
closed forms used here); every run is checked against the closed form and against fmpy running
the same FMU with the same inputs and start values (fmpy records no strings or binaries: those
are checked against the closed form only)."""
from __future__ import annotations

from pathlib import Path

import fmpy
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from orchestrator.component import Component, Var
from orchestrator.errors import SystemError_
from orchestrator.master import Simulation, simulate
from orchestrator.recording import Recording
from orchestrator.system import Connection, System, UnitSpec
from tests.typed_fmus import build_test_fmu

HERE = Path(__file__).parent / "fmus"
H = 0.1
N = 10  # steps of the runs here (stop = 1 s)
FMI2_PAIRS = ["r", "i", "b", "e", "s"]
FMI3_PAIRS = ["f32", "f64", "i8", "u8", "i16", "u16", "i32", "u32", "i64", "u64", "b", "s",
              "bin", "e", "a"]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("typed")
    return {v: build_test_fmu(HERE / f"typed{v}", out) for v in (2, 3)}


def _pair(fmu: Path, names: list[str], a_params=None, b_params=None, record=("b",), **kw) -> System:
    return System(step=H, stop=N * H, units=[UnitSpec("a", fmu=str(fmu), parameters=a_params or {}),
                                             UnitSpec("b", fmu=str(fmu), parameters=b_params or {})],
                  connections=[Connection(f"a.{v}_out", f"b.{v}_in") for v in names],
                  record=list(record), **kw)


def _parity(n):
    return np.asarray(n) % 2 == 1


# ------------------------------------------------------------------ FMI 2

def test_fmi2_every_type_connected_and_recorded(fmus, tmp_path):
    """a (k = 2, state x started at 2) drives b with every type; Gauss-Seidel: b's step n sees
    a's outputs at n."""
    out = tmp_path / "t2.parquet"
    rec = simulate(_pair(fmus[2], FMI2_PAIRS, {"k": 2, "x": 2.0, "s_in": "q", "r_in": 0.25},
                         record=("b", "a.x")), out)
    n = np.arange(N + 1)
    a_r, a_i, a_b, a_e = 0.25 + 0.5 * n, 2 * n, _parity(n), n % 3 + 1
    np.testing.assert_array_equal(rec["b.r_out"], a_r + 0.5 * n)
    np.testing.assert_array_equal(rec["b.i_out"], a_i + n)
    np.testing.assert_array_equal(rec["b.b_out"], a_b != _parity(n))
    np.testing.assert_array_equal(rec["b.e_out"], (a_e - 1 + n) % 3 + 1)
    assert list(rec["b.s_out"]) == [f"q#{k}#{k}" for k in n]
    np.testing.assert_allclose(rec["a.x"], 2.0 + n * H, rtol=0, atol=1e-12)  # the state's start
    np.testing.assert_allclose(rec["b.x"], 1.0 + n * H, rtol=0, atol=1e-12)

    schema = pq.read_schema(out)
    assert [schema.field(c).type for c in ("b.r_out", "b.i_out", "b.b_out", "b.e_out", "b.s_out")] \
        == [pa.float64(), pa.int32(), pa.bool_(), pa.int32(), pa.string()]
    back = Recording.load(out)
    assert list(back["b.s_out"]) == list(rec["b.s_out"])
    np.testing.assert_array_equal(back["b.i_out"], rec["b.i_out"])

    # fmpy: b alone, its inputs at t_k being a's outputs at k + 1 (what Gauss-Seidel gives it)
    t = n * H
    inp = np.zeros(N + 1, dtype=[("time", float), ("r_in", float), ("i_in", np.int32),
                                 ("b_in", bool), ("e_in", np.int32)])
    inp["time"], inp["r_in"], inp["i_in"] = t, 0.25 + 0.5 * (n + 1), 2 * (n + 1)
    inp["b_in"], inp["e_in"] = _parity(n + 1), (n + 1) % 3 + 1
    ref = fmpy.simulate_fmu(str(fmus[2]), stop_time=N * H, step_size=H, output_interval=H,
                            input=inp, start_values={"s_in": "q"})
    for name in ("r_out", "i_out", "b_out", "e_out", "x"):
        np.testing.assert_array_equal(rec[f"b.{name}"][1:], ref[name][1:], err_msg=name)
    a_ref = fmpy.simulate_fmu(str(fmus[2]), stop_time=N * H, step_size=H, output_interval=H,
                              start_values={"k": 2, "x": 2.0, "r_in": 0.25})
    np.testing.assert_array_equal(rec["a.x"], a_ref["x"])


class Source(Component):
    """A Python component with one output of each type a component declares."""

    variables = [Var("r", "output"), Var("i", "output", "Integer", 0),
                 Var("b", "output", "Boolean", False), Var("s", "output", "String", "")]

    def initialize(self, t0: float) -> None:
        self.n = 0
        self._set()

    def _set(self) -> None:
        self["r"], self["i"], self["b"], self["s"] = 1.5 * self.n, 3 * self.n, self.n % 3 == 0, f"c{self.n}"

    def do_step(self, t: float, h: float) -> None:
        self.n += 1
        self._set()


def test_python_component_drives_every_fmi2_type(fmus):
    """Real, Integer (into an Integer and into an Enumeration), Boolean, String from Python."""
    sysm = System(step=H, stop=N * H, units=[
        UnitSpec("c", component=Source("c")), UnitSpec("b", fmu=str(fmus[2]))],
        connections=[Connection("c.r", "b.r_in"), Connection("c.i", "b.i_in"),
                     Connection("c.b", "b.b_in"), Connection("c.s", "b.s_in")],
        record=["b"])
    rec = simulate(sysm)
    n = np.arange(N + 1)
    np.testing.assert_array_equal(rec["b.r_out"], 1.5 * n + 0.5 * n)
    np.testing.assert_array_equal(rec["b.i_out"], 3 * n + n)
    np.testing.assert_array_equal(rec["b.b_out"], (n % 3 == 0) != _parity(n))
    assert list(rec["b.s_out"]) == [f"c{k}#{k}" for k in n]
    # an Integer into an Enumeration is the same integers
    sysm.connections = [Connection("c.i", "b.e_in")]
    sysm.record = ["b.e_out"]
    sysm.units[0] = UnitSpec("c", component=Source("c"))
    # c.i = 3 n is not an item of the enumeration at every n, but the FMU takes integers
    rec = simulate(sysm)
    np.testing.assert_array_equal(rec["b.e_out"], np.fmod(3 * n - 1 + n, 3) + 1)  # C's %


def test_fmi2_boolean_connection_stays_off_the_real_setter(fmus):
    """The native loop exchanges only Real and Integer: a unit with a Boolean or String
    exchange steps on the Python path (setBoolean), Float64-only units stay native."""
    sim = Simulation(_pair(fmus[2], ["b"]))
    sim.load()
    sim.run()
    assert not sim._native_ok("b")
    sim = Simulation(_pair(fmus[2], ["r", "i", "e"], record=("b.r_out",)))
    sim.load()
    sim.run()
    assert sim._native_ok("a") and sim._native_ok("b")


# ------------------------------------------------------------------ FMI 3

def test_fmi3_every_type_and_an_array(fmus, tmp_path):
    out = tmp_path / "t3.parquet"
    a_params = {"i8_in": -3, "u8_in": 7, "i64_in": 2**40, "u64_in": 2**63, "f32_in": 0.25,
                "s_in": "q", "bin_in": "beef", "e_in": 2, "a_in": [1.0, 2.0, 3.0], "x": 2.0,
                "b_in": True, "u32_in": 4_000_000_000}
    rec = simulate(_pair(fmus[3], FMI3_PAIRS, a_params, record=("b", "a")), out)
    n = np.arange(N + 1)
    for name, a0 in (("i8", -3), ("u8", 7), ("i16", 0), ("u16", 0), ("i32", 0), ("u32", 4_000_000_000),
                     ("i64", 2**40), ("u64", 2**63)):
        assert [int(x) for x in rec[f"a.{name}_out"]] == [a0 + int(k) for k in n], name
        assert [int(x) for x in rec[f"b.{name}_out"]] == [a0 + 2 * int(k) for k in n], name
    np.testing.assert_array_equal(rec["b.f32_out"], np.float32(0.25) + np.float32(0.5) * 2 * n)
    np.testing.assert_array_equal(rec["b.f64_out"], 1.0 * n)
    np.testing.assert_array_equal(rec["b.b_out"], np.full(N + 1, True))
    np.testing.assert_array_equal(rec["b.e_out"], (2 - 1 + 2 * n) % 3 + 1)
    assert list(rec["b.s_out"]) == [f"q#{k}#{k}" for k in n]
    assert list(rec["b.bin_out"]) == [bytes([0xBE, 0xEF, k, k]) for k in n]
    for i in range(3):  # a_out[i] = a_in[i] + 0.5 (i + 1) n, twice over
        np.testing.assert_array_equal(rec[f"b.a_out[{i}]"], (i + 1) * (1 + n))
    np.testing.assert_allclose(rec["a.x"], 2.0 + n * H, rtol=0, atol=1e-12)

    types = {"f32": pa.float32(), "f64": pa.float64(), "i8": pa.int8(), "u8": pa.uint8(),
             "i16": pa.int16(), "u16": pa.uint16(), "i32": pa.int32(), "u32": pa.uint32(),
             "i64": pa.int64(), "u64": pa.uint64(), "b": pa.bool_(), "s": pa.string(),
             "bin": pa.binary(), "e": pa.int64()}
    schema = pq.read_schema(out)
    for name, t in types.items():
        assert schema.field(f"b.{name}_out").type == t, name
    assert schema.field("b.a_out[2]").type == pa.float64()
    back = Recording.load(out)
    assert [int(x) for x in back["b.u64_out"]] == [2**63 + 2 * int(k) for k in n]  # no float rounding

    # fmpy: unit a alone with the same start values
    starts = {k: v for k, v in a_params.items() if k not in ("bin_in", "a_in")}
    ref = fmpy.simulate_fmu(str(fmus[3]), stop_time=N * H, step_size=H, output_interval=H,
                            start_values={**starts, "a_in": [1.0, 2.0, 3.0]},
                            output=[f"{v}_out" for v in types if v not in ("s", "bin")] + ["a_out", "x"])
    for v in types:
        if v not in ("s", "bin"):
            assert [x for x in rec[f"a.{v}_out"]] == list(ref[f"{v}_out"]), v
    for i in range(3):
        np.testing.assert_array_equal(rec[f"a.a_out[{i}]"], ref["a_out"][:, i])
    np.testing.assert_array_equal(rec["a.x"], ref["x"])

    # fmpy: b alone, its inputs at t_k being a's outputs at k + 1 (what Gauss-Seidel gives it)
    dtypes = {"f32": np.float32, "f64": float, "i8": np.int8, "u8": np.uint8, "i16": np.int16,
              "u16": np.uint16, "i32": np.int32, "u32": np.uint32, "i64": np.int64,
              "u64": np.uint64, "b": bool, "e": np.int64}
    inp = np.zeros(N + 1, dtype=[("time", float)] + [(f"{v}_in", d) for v, d in dtypes.items()])
    arr = np.zeros(N + 1, dtype=[("time", float), ("a_in", float, (3,))])
    inp["time"] = arr["time"] = n * H
    nxt = np.minimum(n + 1, N)
    for v, d in dtypes.items():
        inp[f"{v}_in"] = np.array(list(rec[f"a.{v}_out"]), dtype=d)[nxt]
    arr["a_in"] = np.stack([rec[f"a.a_out[{i}]"][nxt] for i in range(3)], axis=1)
    # two runs: fmpy cannot stack a scalar and an array Float64 input in one table
    ref_b = fmpy.simulate_fmu(str(fmus[3]), stop_time=N * H, step_size=H, output_interval=H,
                              input=inp, output=[f"{v}_out" for v in dtypes])
    ref_a = fmpy.simulate_fmu(str(fmus[3]), stop_time=N * H, step_size=H, output_interval=H,
                              input=arr, output=["a_out"])
    for v in dtypes:
        assert list(rec[f"b.{v}_out"])[1:] == list(ref_b[f"{v}_out"])[1:], v
    for i in range(3):
        np.testing.assert_array_equal(rec[f"b.a_out[{i}]"][1:], ref_a["a_out"][1:, i])


@pytest.mark.parametrize("src, dst, ok", [
    ("i8", "i32", True), ("f32", "f64", True), ("u16", "i32", True), ("e", "i64", True),
    ("i64", "i32", False), ("f64", "i32", False), ("b", "i32", False), ("u32", "i32", False),
    ("f64", "f32", False), ("s", "bin", False),
])
def test_fmi3_connections_only_where_lossless(fmus, src, dst, ok):
    sysm = System(step=H, stop=N * H, units=[UnitSpec("a", fmu=str(fmus[3])),
                                             UnitSpec("b", fmu=str(fmus[3]))],
                  connections=[Connection(f"a.{src}_out", f"b.{dst}_in")])
    if ok:
        Simulation(sysm).load()
        return
    with pytest.raises(SystemError_) as ei:
        Simulation(sysm).load()
    msg = str(ei.value)
    assert f"a.{src}_out is " in msg and f"b.{dst}_in is " in msg and "lossless" in msg
    assert "\n" not in msg


def test_connection_units_checked(fmus):
    """x is in s, r_in in m: refused naming both (r_out, in m, connects)."""
    sysm = _pair(fmus[2], [])
    sysm.connections = [Connection("a.x", "b.r_in")]
    with pytest.raises(SystemError_, match=r"a.x is in s but b.r_in is in m; connected variables "
                                           "need the same unit"):
        Simulation(sysm).load()


def test_fmi3_array_connected_whole_and_recorded_per_element(fmus):
    sysm = _pair(fmus[3], ["a"], {"a_in": [1.0, -1.0, 0.5]}, record=("b.a_out", "a.a_*"))
    rec = simulate(sysm)
    assert rec.signals == ["b.a_out[0]", "b.a_out[1]", "b.a_out[2]", "a.a_in[0]", "a.a_in[1]",
                           "a.a_in[2]", "a.a_out[0]", "a.a_out[1]", "a.a_out[2]"]
    n = np.arange(N + 1)
    for i, a0 in enumerate((1.0, -1.0, 0.5)):
        np.testing.assert_array_equal(rec[f"b.a_out[{i}]"], a0 + (i + 1) * n)
    # a list of the wrong length is refused
    with pytest.raises(SystemError_, match=r"a_in = \[1.0, 2.0\]: expected a list of 3 values"):
        simulate(_pair(fmus[3], [], {"a_in": [1.0, 2.0]}))
    with pytest.raises(SystemError_, match="N sets the size of an array"):
        simulate(_pair(fmus[3], [], {"N": 4}))


# ------------------------------------------------------------------ termination

@pytest.mark.parametrize("version", [2, 3])
def test_fmu_ends_the_run(fmus, tmp_path, version):
    """A Stair-like end: the step that reaches t_end = 8.8 s is the last; recorded to it,
    reported, a normal end (and fmpy stops at the same sample)."""
    sysm = System(step=H, stop=10.0, units=[UnitSpec("s", fmu=str(fmus[version]),
                                                     parameters={"t_end": 8.8})],
                  record=["s.x", "s.r_out" if version == 2 else "s.f64_out"])
    sim = Simulation(sysm)
    rec = sim.run(tmp_path / "end.parquet")
    assert sim.stopped_at == pytest.approx(8.8)
    assert rec.complete and rec.rows == 89
    np.testing.assert_allclose(rec.t[-1], 8.8)
    np.testing.assert_allclose(rec["s.x"], 1.0 + rec.t, rtol=0, atol=1e-9)
    ref = fmpy.simulate_fmu(str(fmus[version]), stop_time=10.0, step_size=H, output_interval=H,
                            start_values={"t_end": 8.8}, output=["x"])
    assert len(ref) == rec.rows
    # fmpy passes step sizes next - t (ulps apart from h): the state agrees to rounding
    np.testing.assert_allclose(rec["s.x"], ref["x"], rtol=0, atol=1e-12)
    saved = Recording.load(tmp_path / "end.parquet")
    assert saved.rows == 89 and saved.provenance["system"]["stopped_at"] == pytest.approx(8.8)


@pytest.mark.parametrize("version, pairs", [(2, ["r"]), (2, ["r", "b"]), (3, ["f64", "b"])])
@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_fmu_ending_mid_system_completes_the_step(fmus, version, pairs, algorithm):
    """The unit that ends the run is first in the order: the unit after it still takes that
    step, so the last row is whole. FMI 2 Real only: in the native loop; with a Boolean: on
    the Python path."""
    sim = Simulation(_pair(fmus[version], pairs, {"t_end": 0.5}, algorithm=algorithm,
                           record=(f"b.{pairs[0]}_out", "b.b_out")))
    rec = sim.run()
    assert rec.rows == 6 and sim.stopped_at == pytest.approx(0.5)
    assert sim._native_ok("a") == (version == 2 and "b" not in pairs)
    n = np.arange(6)
    # b's real output: a's output (of step n, Jacobi: of step n - 1) + 0.5 n
    a_out = 0.5 * (n if algorithm == "gauss-seidel" else np.maximum(n - 1, 0))
    np.testing.assert_array_equal(rec[f"b.{pairs[0]}_out"], a_out + 0.5 * n)


@pytest.mark.parametrize("every, t_end", [(4, 8.8), (25, 8.8), (30, 9.5)])
def test_fmu_ending_between_recorded_rows(fmus, every, t_end):
    """Recording every 4th step, the end at 8.8 s (step 88) is on the grid; every 25th, it
    falls between rows (7.5 s and 10 s); every 30th, an end at 9.5 s comes after the grid's
    last row (9 s). Its sample is recorded in every case."""
    sysm = System(step=H, stop=10.0, units=[UnitSpec("s", fmu=str(fmus[2]),
                                                     parameters={"t_end": t_end})],
                  record=["s.x"], record_every=every)
    rec = simulate(sysm)
    k = round(t_end / H)
    assert rec.t[-1] == pytest.approx(t_end) and rec.rows == k // every + 1 + (k % every > 0)
    np.testing.assert_allclose(rec["s.x"], 1.0 + rec.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.diff(rec.t[:-1]), every * H)


def test_cli_run_of_an_ending_fmu_exits_0(fmus, tmp_path, capsys, monkeypatch):
    from components.cli import main

    (tmp_path / "sys.toml").write_text(
        f'[system]\nstep = 0.1\nstop = 10.0\n[units.s]\nfmu = "{fmus[2]}"\n'
        '[units.s.parameters]\nt_end = 8.8\n[record]\nsignals = ["s"]\n')
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(tmp_path / "sys.toml")]) == 0
    out = capsys.readouterr().out
    assert "a unit ended the run at t = 8.8 s" in out and "89 rows" in out


# ------------------------------------------------------------------ start values

@pytest.mark.parametrize("version, params, match", [
    (2, {"r_out": 1.0}, 'r_out is a output with initial="calculated", not settable'),
    (2, {"k": 7.5}, r"k = 7.5: expected an integer \(a value with a fraction is not rounded\)"),
    (2, {"k": True}, "k = True: expected an integer, not a Boolean"),
    (2, {"b_in": 1}, "b_in = 1: expected true or false"),
    (2, {"s_in": 3}, "s_in = 3: expected a string"),
    (3, {"i8_in": 200}, r"i8_in = 200: expected an integer in \[-128, 127\]"),
    (3, {"u64_in": -1}, r"expected an integer in \[0, 18446744073709551615\]"),
    (3, {"bin_in": "xyz"}, "expected bytes, or a string of hexadecimal digits"),
    (3, {"x": "1"}, "x = '1': expected a number"),
])
def test_start_values_refused(fmus, version, params, match):
    with pytest.raises(SystemError_, match=match) as ei:
        simulate(_pair(fmus[version], [], params))
    assert "units.a.parameters" in str(ei.value) and "\n" not in str(ei.value)


def test_string_read_before_its_source_gave_one(fmus):
    """A loop of strings broken by the order: at initialisation b reads a's output before a
    has one and gets the empty string (as a float input gets 0.0)."""
    sysm = System(step=H, stop=N * H, order=["b", "a"],
                  units=[UnitSpec("a", fmu=str(fmus[2])), UnitSpec("b", fmu=str(fmus[2]))],
                  connections=[Connection("a.s_out", "b.s_in"), Connection("b.s_out", "a.s_in")],
                  record=["b.s_out"])
    rec = simulate(sysm)
    assert rec["b.s_out"][0] == "#0" and rec["b.s_out"][1] == "#0#0#1"


def test_integral_float_is_an_integer(fmus):
    rec = simulate(_pair(fmus[2], [], {"k": 3.0, "i_in": 1}, record=("a.i_out",)))
    np.testing.assert_array_equal(rec["a.i_out"], 1 + 3 * np.arange(N + 1))


# ------------------------------------------------------------------ the grid and recording

def test_stop_between_steps_shortens_the_last_step(fmus):
    sysm = System(step=H, stop=1.05, units=[UnitSpec("a", fmu=str(fmus[2]))], record=["a.x"])
    sim = Simulation(sysm)
    rec = sim.run()
    assert rec.rows == 12 and rec.t[-1] == pytest.approx(1.05)
    np.testing.assert_allclose(rec["a.x"], 1.0 + rec.t, rtol=0, atol=1e-12)
    assert any("shortened to 0.05 s" in n for n in sim.notes)
    ref = fmpy.simulate_fmu(str(fmus[2]), stop_time=1.05, step_size=H, output_interval=H, output=["x"])
    np.testing.assert_allclose(rec["a.x"], ref["x"], rtol=0, atol=1e-12)
    assert rec.provenance["notes"] == sim.notes
    # a unit stepping at a multiple of the step could not take the short step: refused
    sysm.units[0].step_multiple = 2
    with pytest.raises(SystemError_, match=r"not a whole number of steps of 0.1, and units \['a'\] "
                                           "step at a multiple of it"):
        Simulation(sysm).run()


def test_record_whole_unit_and_patterns(fmus):
    rec = simulate(_pair(fmus[2], [], record=("a", "b.?_out", "b.r_*")))
    assert rec.signals == ["a.r_out", "a.i_out", "a.b_out", "a.e_out", "a.s_out", "a.x",
                           "b.r_out", "b.i_out", "b.b_out", "b.e_out", "b.s_out", "b.r_in"]
    with pytest.raises(SystemError_, match=r"record.signals: 'b.zz\*': no variable of unit b matches"):
        simulate(_pair(fmus[2], [], record=("b.zz*",)))


def test_clocked_fmu_refused_saying_why(tmp_path):
    """An FMI 3 variable type the master cannot exchange (a Clock) is named at load."""
    from orchestrator.errors import UnitError
    from orchestrator.fmu_units import load_fmu_unit

    folder = tmp_path / "clocked"
    folder.mkdir()
    (folder / "model.c").write_text((HERE / "typed3" / "model.c").read_text())
    md = (HERE / "typed3" / "modelDescription.xml").read_text().replace(
        "  </ModelVariables>", '    <Clock name="tick" valueReference="300" causality="input" '
        'intervalVariability="triggered"/>\n  </ModelVariables>')
    (folder / "modelDescription.xml").write_text(md)
    fmu = build_test_fmu(folder, tmp_path)
    with pytest.raises(UnitError, match=f"unit c: {fmu}: variable tick is a Clock: clocked "
                                        r"co-simulation \(event mode\) is not supported"):
        load_fmu_unit("c", fmu)
