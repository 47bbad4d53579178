"""The trials of "Nothing silently wrong, round 4", re-run and classified: each in a child
process with a time limit, against this checkout or an older one.

    python benchmarks/round4_trials.py [--old CHECKOUT] [--timeout 20]

--old runs the same trials on another checkout (its Python package and the native FMUs
its `python build_fmu.py --native` built), e.g. `git worktree add /tmp/old v0.4.0`.
Classes: ok (a right answer, or a refusal naming the value and the remedy), silent (a
wrong answer with status OK or exit 0), hang (no answer within the limit), crash (killed
by a signal), unclear (refused without naming the cause), noise (a success that prints
errors or tracebacks). Exit 1 if any trial is not ok.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]

#: name -> (what the issue found, Python code printing one JSON verdict line)
TRIALS: dict[str, tuple[str, str]] = {}


def trial(name: str, found: str):
    def add(fn):
        TRIALS[name] = (found, textwrap.dedent(fn.__doc__))
        return fn
    return add


PRELUDE = textwrap.dedent("""
    import json, math, shutil, struct, sys, time, zipfile
    from pathlib import Path
    import fmpy
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave
    FMUS = Path(sys.argv[1])
    def say(cls, why): print(json.dumps({"class": cls, "why": why})); sys.exit(0)
    def observer(params, ux, version=2, steps=1, h=5e-6):
        path = str(FMUS / f"fmi{version}" / "GyroObserver.fmu")
        md = fmpy.read_model_description(path)
        vr = {v.name: v.valueReference for v in md.modelVariables}
        d = fmpy.extract(path)
        Slave = FMU2Slave if version == 2 else FMU3Slave
        s = Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="o")
        s.instantiate()
        if version == 2:
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
        else:
            s.enterInitializationMode(startTime=0.0)
        for k, v in params.items():
            s.setFloat64([vr[k]], [v]) if version == 3 else s.setReal([vr[k]], [v])
        s.exitInitializationMode()
        (s.setFloat64 if version == 3 else s.setReal)([vr["ux"]], [ux])
        try:
            for k in range(steps):
                s.doStep(k * h, h)
        except Exception as exc:
            return None, str(exc)
        get = s.getFloat64 if version == 3 else s.getReal
        return get([vr["x_hat"], vr["vx_hat"], vr["status"]]), ""
""")


def _observer_trial(params: str, ux: str, version: int, ref_ux: str, scale: str) -> str:
    """The first prediction from rest is linear in b ux: it must be `scale` times the
    default observer's for ref_ux."""
    return f"""
        t0 = time.perf_counter()
        out, err = observer({params}, {ux}, version={version})
        took = time.perf_counter() - t0
        if out is None:
            say("ok", "refused: " + err)
        ref, _ = observer({{}}, {ref_ux}, version={version})
        want = ({scale}) * ref[0]
        if out[2] == 0 and out[0] == 0.0:
            say("silent", f"status OK with x_hat = {{out[0]}} (expected {{want:.4g}})")
        if took > 2.0:
            say("hang", f"one step took {{took:.1f}} s")
        if abs(out[0] - want) <= 1e-9 * abs(want):
            say("ok", f"x_hat {{out[0]:.6g}} = the linear prediction, in {{took:.3f}} s")
        say("silent", f"x_hat {{out[0]}} != {{want}} with status {{out[2]}}")
    """


for v in (2, 3):
    TRIALS[f"observer ux=1e13 N, FMI {v}"] = (
        "silent: x_hat = vx_hat = 0, status OK", _observer_trial("{}", "1e13", v, "1.0", "1e13"))
    TRIALS[f"observer m_0=1e-22 kg, FMI {v}"] = (
        "silent: x_hat = vx_hat = 0, status OK", _observer_trial(
            '{"m_0": 1e-22}', "1e-6", v, "1e-6", "1.89e-7 / 1e-22"))
TRIALS["observer ux=1e9 N (one step)"] = ("hang: 7-40 s a step", _observer_trial(
    "{}", "1e9", 2, "1.0", "1e9"))
TRIALS["observer m_0=1e-16 kg, ux=1e-3 N"] = ("hang: 7-40 s a step", _observer_trial(
    '{"m_0": 1e-16}', "1e-3", 2, "1e-3", "1.89e-7 / 1e-16"))


@trial("GyroLoops sideband_count=2e9", "hang: the first step never ends")
def _loops():
    """
    path = str(FMUS / "fmi2" / "GyroLoops.fmu")
    md = fmpy.read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(path),
                  modelIdentifier="GyroLoops", instanceName="l")
    msgs = []
    from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    try:
        s.setInteger([vr["sideband_count"]], [2000000000])
        s.setReal([vr["sideband_index"]], [0.01])
        s.enterInitializationMode(); s.exitInitializationMode()
        s.doStep(0.0, 1e-5)
    except Exception as exc:
        say("ok", "refused: " + str(exc))
    say("ok", "stepped")
    """


def _state_trial(model: str, value: str) -> str:
    """Every 8-byte slot of a saved state's model data set to `value`, one at a time, then
    restored and stepped: refused, or stepped with finite outputs (a slot the model does
    not read), is right; a step with status OK and non-finite outputs is silent."""
    return f"""
        path = str(FMUS / "fmi2" / "{model}.fmu")
        md = fmpy.read_model_description(path)
        outs = [v.valueReference for v in md.modelVariables if v.causality == "output"
                and v.type == "Real"]
        s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(path),
                      modelIdentifier="{model}", instanceName="s")
        s.instantiate(); s.setupExperiment(startTime=0.0)
        s.enterInitializationMode(); s.exitInitializationMode()
        for k in range(3):
            s.doStep(k * 5e-6, 5e-6)
        st = s.getFMUstate()
        good = bytes(s.serializeFMUstate(st))
        header = 8 + 4 + 4 + 64 + 4 + 16 + 1024
        refused = stepped = failed = 0
        for at in range(header, len(good) - 7, 8):
            raw = bytearray(good)
            raw[at:at + 8] = struct.pack('<d', {value})
            try:
                s.setFMUstate(s.deSerializeFMUstate(bytes(raw)))
            except Exception:
                refused += 1
                continue
            try:
                s.doStep(15e-6, 5e-6)
            except Exception:
                failed += 1
                s.setFMUstate(st)
                continue
            if not all(math.isfinite(x) for x in s.getReal(outs)):
                say("silent", f"slot at byte {{at}} = {value}: step OK, non-finite outputs")
            stepped += 1
            s.setFMUstate(st)
        say("ok", f"{{refused}} slots refused at restore, {{failed}} refused at the step, "
                  f"{{stepped}} stepped with finite outputs")
    """


TRIALS["GyroResonator state, each slot inf (deserialized)"] = (
    "undefined behaviour (s++ overflow), then an endless loop",
    _state_trial("GyroResonator", "math.inf"))
TRIALS["GyroObserver state, each slot NaN (deserialized)"] = (
    "undefined behaviour: NaN converted to int in the held step",
    _state_trial("GyroObserver", "math.nan"))


def _validate_trial(argv: str, tamper: str) -> str:
    return f"""
        import subprocess
        src = FMUS / "fmi2" / "GyroPlant.fmu"
        bad = Path("GyroPlant.fmu")
        with zipfile.ZipFile(src) as zin, zipfile.ZipFile(bad, "w") as zout:
            for item in zin.infolist():
                data = zin.read(item)
                {tamper}
                zout.writestr(item, data)
        p = subprocess.run([sys.executable, "-m", "gyro_fmu.cli", "validate", *{argv},
                            str(bad)], capture_output=True, text=True)
        text = p.stdout + p.stderr
        if p.returncode == 0:
            say("silent", "exit 0: " + text.strip().splitlines()[-1])
        last = [l for l in text.splitlines() if "FAIL" in l or "error" in l]
        said = (last or text.strip().splitlines())[0]
        say("unclear" if "communication points" in text else "ok", said[:200])
    """


DOUBLE_X = """if item.filename.endswith("GyroPlant_out.csv"):
                    lines = data.decode().splitlines()
                    j = [h.strip('"') for h in lines[0].split(",")].index("x")
                    rows = [lines[0]]
                    for line in lines[1:]:
                        c = line.split(","); c[j] = repr(2 * float(c[j])); rows.append(",".join(c))
                    data = ("\\n".join(rows) + "\\n").encode()"""
TRIALS["validate --dx 300, reference x doubled"] = (
    "silent: all outputs match, exit 0", _validate_trial('["--dx", "300"]', DOUBLE_X))
TRIALS["validate --dx 100000, reference x doubled"] = (
    "silent: all outputs match, exit 0", _validate_trial('["--dx", "100000"]', DOUBLE_X))
TRIALS["validate, negative default stepSize"] = (
    "unclear: '-1999 communication points'", _validate_trial(
        "[]", """if item.filename == "modelDescription.xml":
                    data = data.replace(b'stepSize="5e-06"', b'stepSize="-5e-06"')"""))


@trial("container with the patent scenario", "unclear: fails at ExitInitializationMode")
def _container():
    """
    import subprocess, shutil
    models = Path("models"); models.mkdir()
    for f in (FMUS / "fmi2").glob("*.fmu"):
        shutil.copy(f, models)
    code = ("from gyro_fmu.system.container import build_container, container_start_values\\n"
            "from gyro_fmu.system.scenario import scenario\\nimport fmpy\\n"
            "c = build_container(__import__('pathlib').Path('models'))\\n"
            "sv = container_start_values(scenario('patent', stop_time=0.001))\\n"
            "fmpy.simulate_fmu(str(c), stop_time=0.001, output_interval=5e-6, start_values=sv)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    text = p.stdout + p.stderr
    if p.returncode == 0:
        say("ok", "ran")
    last = text.strip().splitlines()[-1]
    if "run this scenario with" in text:
        say("ok", "refused before the run: " + last[-200:])
    say("unclear", last[-200:])
    """


@trial("run whose verdict fails (Omega_z_0 0.5 held)", "silent: verdict False, exit 0")
def _verdict():
    """
    import subprocess, shutil
    models = Path("models"); models.mkdir()
    for f in (FMUS / "fmi2").glob("*.fmu"):
        shutil.copy(f, models)
    p = subprocess.run([sys.executable, "-m", "gyro_fmu.cli", "run", "--stop-time", "0.005",
                        "--no-figures", "--tuning", "rate_model=1", "--tuning",
                        "sigma0_Omega=1e-6", "--Omega-z-0", "0.5"], capture_output=True,
                       text=True)
    if p.returncode == 0:
        say("silent", "exit 0 with Omega_hat 0.5 off by 50 %")
    say("ok", f"exit {p.returncode}: " + p.stdout.strip().splitlines()[-2][:150])
    """


@trial("a second run with other settings into runs/default", "silent: replaces the first")
def _replace():
    """
    import subprocess, shutil
    models = Path("models"); models.mkdir()
    for f in (FMUS / "fmi2").glob("*.fmu"):
        shutil.copy(f, models)
    cli = [sys.executable, "-m", "gyro_fmu.cli", "run", "--no-figures"]
    subprocess.run([*cli, "--stop-time", "0.002"], capture_output=True)
    p = subprocess.run([*cli, "--stop-time", "0.003"], capture_output=True, text=True)
    if p.returncode == 0:
        say("silent", "the first run was replaced without a word")
    say("ok", p.stderr.strip()[-200:])
    """


@trial("gyro-fmu container prints errors on success", "noise: [ERROR] Solver configure....")
def _container_noise():
    """
    import subprocess, shutil
    models = Path("models"); models.mkdir()
    for f in (FMUS / "fmi2").glob("*.fmu"):
        shutil.copy(f, models)
    p = subprocess.run([sys.executable, "-m", "gyro_fmu.cli", "container"], capture_output=True,
                       text=True)
    text = p.stdout + p.stderr
    if p.returncode != 0:
        say("unclear", text[-200:])
    say("noise" if "[ERROR]" in text or "Traceback" in text else "ok", text.strip()[-120:])
    """


def run_trial(code: str, fmus: Path, pythonpath: str, timeout: float) -> tuple[str, str]:
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "trial.py"
        script.write_text(PRELUDE + textwrap.dedent(code))
        env = {**os.environ, "PYTHONPATH": pythonpath}
        try:
            p = subprocess.run([sys.executable, str(script), str(fmus)], capture_output=True,
                               text=True, timeout=timeout, cwd=tmp, env=env)
        except subprocess.TimeoutExpired:
            return "hang", f"no answer in {timeout:g} s"
        if p.returncode < 0:
            return "crash", f"killed by signal {-p.returncode}"
        for line in reversed(p.stdout.splitlines()):
            if line.startswith("{"):
                v = json.loads(line)
                return v["class"], v["why"]
        return "unclear", (p.stderr.strip().splitlines() or ["no output"])[-1][:200]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--old", type=Path, help="another checkout to run the trials on")
    ap.add_argument("--timeout", type=float, default=20.0)
    args = ap.parse_args()
    root = (args.old or HERE).resolve()
    fmus = root / "gyro_fmu" / "fmus"
    if not (fmus / "fmi2" / "GyroObserver.fmu").exists():
        print(f"no native FMUs in {fmus}: run `python build_fmu.py --native` there")
        return 2
    counts: dict[str, int] = {}
    print(f"{'trial':<48} {'class':<8} what happened (the issue found)")
    for name, (found, code) in TRIALS.items():
        cls, why = run_trial(code, fmus, str(root), args.timeout)
        counts[cls] = counts.get(cls, 0) + 1
        print(f"{name:<48} {cls:<8} {why[:110]}  ({found})", flush=True)
    print(", ".join(f"{k}: {v}" for k, v in sorted(counts.items())))
    return 0 if set(counts) == {"ok"} else 1


if __name__ == "__main__":
    raise SystemExit(main())
