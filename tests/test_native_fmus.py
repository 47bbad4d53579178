"""The native FMUs (C core + FMI layer) against gyro_fmu 0.2.0's implementation, the
in-process library and the pythonfmu flavour, in FMI 2.0 and 3.0, through fmpy.

Tolerances: the core keeps 0.2.0's operation order, every object is compiled with
-ffp-contract=off (no fused multiply-add) and the sine is the platform's libm, which
Python's math.sin calls too; so noise-free outputs are compared bit for bit (tolerance 0),
and a failure means the arithmetic changed. The noise generator is new (xoshiro256** and
the polar method, not numpy's PCG64 and ziggurat): noisy outputs are compared bit for bit
between the flavours (one core), and against the oracle by their statistics.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from native_host import NativeRun
from oracle_v02 import Plant, drive_ux, rate_Omega_z

from gyro_fmu.fmu.build import prebuilt_fmu
from gyro_fmu.model.drive import TwoToneDrive
from gyro_fmu.model.interfaces import PLANT
from gyro_fmu.model.parameters import PARAMETER_NAMES, PRESETS, GyroParameters
from gyro_fmu.model.plant import GyroPlantModel, MeasurementNoise
from gyro_fmu.model.rate import RateKind, RateProfile

OUTPUTS = ["x", "vx", "y", "vy", "ax", "ay"]
VERSIONS = (2, 3)


def random_gyro(rng: np.random.Generator) -> GyroParameters:
    """A gyro that is no preset: modes 1-12 kHz, |kxy| up to 0.6 sqrt(kxx kyy), dampings
    0-200 1/s, cross damping of either sign, mass 1e-9 .. 1 kg."""
    kxx, kyy = (2 * math.pi * rng.uniform(1e3, 12e3, 2)) ** 2
    kxy = rng.uniform(-0.6, 0.6) * math.sqrt(kxx * kyy)
    dxx, dyy = rng.uniform(0.0, 200.0, 2)
    dxy = rng.uniform(-0.5, 0.5) * min(dxx, dyy)
    return GyroParameters(kxx, kyy, kxy, dxx, dyy, dxy, 10 ** rng.uniform(-9, 0))


def oracle_rows(p: GyroParameters, steps, ux, Omega) -> np.ndarray:
    o = Plant(p)
    rows = [o.outputs()]
    for k, h in enumerate(steps):
        o.step(float(ux[k]), 0.0, float(Omega[k]), float(h))
        rows.append(o.outputs())
    return np.array(rows)


def native_rows(version: int, p: GyroParameters, steps, ux, Omega, **noise) -> np.ndarray:
    run = NativeRun(prebuilt_fmu("GyroPlant", version))
    try:
        run.initialize(**{n: getattr(p, n) for n in PARAMETER_NAMES}, **noise)
        return run.run(steps, OUTPUTS, {"ux": ux, "Omega_z": Omega})
    finally:
        run.close()


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("case", ["default", "patent"])
def test_plant_equals_the_0_2_oracle_bit_for_bit(version: int, case: str) -> None:
    """The default scenario (park-horowitz, 1e-7 N tones, 1 rad/s) and the patent's
    (Table 1 corrected, 1 N tones, sin(2 pi 100 t)): 400 steps of 5 us."""
    h, n = 5e-6, 400
    t = np.arange(n) * h
    if case == "default":
        p, A, Omega = PRESETS["park-horowitz"], 1e-7, np.ones(n)
    else:
        p, A, Omega = PRESETS["patent-table1-corrected"], 1.0, np.sin(2 * np.pi * 100 * t)
    ux = np.array([drive_ux(A, 4000.0, A, 1200.0, tk) for tk in t])
    got = native_rows(version, p, np.full(n, h), ux, Omega)
    want = oracle_rows(p, np.full(n, h), ux, Omega)
    assert np.array_equal(got, want), np.max(np.abs(got - want), axis=0)


@pytest.mark.parametrize("version", VERSIONS)
def test_plant_on_20_random_gyros_with_variable_steps(version: int) -> None:
    """20 gyros that are no preset, steps drawn in 2-20 us, a random drive and a sine
    rate: noise-free outputs equal the oracle's bit for bit."""
    rng = np.random.default_rng(2026 + version)
    for _ in range(20):
        p = random_gyro(rng)
        n = 40
        steps = rng.uniform(2e-6, 20e-6, n)
        t = np.concatenate([[0.0], np.cumsum(steps)[:-1]])
        A = 1e-9 * p.m * p.kxx
        ux = A * np.sin(2 * np.pi * rng.uniform(500, 8000) * t)
        Omega = rng.uniform(-5, 5) * np.sin(2 * np.pi * rng.uniform(0, 500) * t)
        got = native_rows(version, p, steps, ux, Omega)
        want = oracle_rows(p, steps, ux, Omega)
        assert np.array_equal(got, want), (p, np.max(np.abs(got - want), axis=0))


@pytest.mark.parametrize("version", VERSIONS)
def test_noisy_plant_equals_the_library_and_its_noise_is_white(version: int) -> None:
    """With noise and seeds, the FMU equals the in-process library (one core) bit for bit;
    its measured-minus-true signals are N(0, sigma^2): mean within 4 sigma/sqrt(N), std
    within 5 %, lag-1 correlation below 0.1 (N = 2001 draws per signal)."""
    rng = np.random.default_rng(7)
    p = random_gyro(rng)
    n, h = 2000, 7e-6
    steps = np.full(n, h)
    ux = 1e-9 * p.m * p.kxx * np.sin(2 * np.pi * 3000 * np.arange(n) * h)
    Omega = np.full(n, 0.7)
    sigma = {"noise_x": 1e-12, "noise_vx": 3e-8, "noise_y": 2e-12, "noise_vy": 4e-8}
    for seed in (0, 123456789, 2**31 - 1):
        got = native_rows(version, p, steps, ux, Omega, seed=seed, **sigma)
        lib = GyroPlantModel(p, MeasurementNoise(*sigma.values()), seed)
        rows = [lib.output_row()]
        for k in range(n):
            lib.step(float(ux[k]), 0.0, 0.7, h)
            rows.append(lib.output_row())
        assert np.array_equal(got, np.array(rows))
        noise = got[:, :4] - oracle_rows(p, steps, ux, Omega)[:, :4]
        for j, s in enumerate(sigma.values()):
            e = noise[:, j] / s
            assert abs(e.mean()) < 4 / math.sqrt(e.size)
            assert abs(e.std() - 1) < 0.05
            assert abs(np.corrcoef(e[:-1], e[1:])[0, 1]) < 0.1
    seeds = [native_rows(version, p, steps[:50], ux, Omega, seed=s, **sigma) for s in (1, 2)]
    assert not np.array_equal(*seeds)


@pytest.mark.parametrize("version", VERSIONS)
def test_drive_and_rate_equal_the_oracle(version: int) -> None:
    """TwoToneDrive and RateProfile (every kind) with random settings and steps."""
    rng = np.random.default_rng(11)
    for _ in range(10):
        A1, A2 = rng.uniform(-2, 2, 2)
        f1, f2 = rng.uniform(0, 2e4, 2)
        steps = rng.uniform(1e-6, 3e-5, 30)
        t = np.concatenate([[0.0], np.cumsum(steps)])
        run = NativeRun(prebuilt_fmu("TwoToneDrive", version))
        run.initialize(A1=A1, f1=f1, A2=A2, f2=f2)
        got = run.run(steps, ["ux", "uy"])
        run.close()
        want = np.array([drive_ux(A1, f1, A2, f2, tk) for tk in np.cumsum([0, *steps])])
        assert np.array_equal(got[:, 0], want) and not got[:, 1].any()
        assert np.array_equal(TwoToneDrive(A1, f1, A2, f2).ux_many(t), want)
        for kind in RateKind:
            values = dict(offset=rng.uniform(-3, 3), amplitude=rng.uniform(-3, 3),
                          frequency=rng.uniform(0, 1e3), slope=rng.uniform(-1e3, 1e3),
                          t_start=rng.uniform(0, 3e-4))
            run = NativeRun(prebuilt_fmu("RateProfile", version))
            run.initialize(kind=int(kind), **values)
            got = run.run(steps, ["Omega_z"])[:, 0]
            run.close()
            want = np.array([rate_Omega_z(int(kind), *values.values(), tk)
                             for tk in np.cumsum([0, *steps])])
            assert np.array_equal(got, want), kind
            assert np.array_equal(RateProfile(kind, **values).Omega_z_many(t), want)


def test_the_interfaces_generate_the_model_descriptions() -> None:
    """Every declared variable, with its unit, bounds and start, is in both model
    descriptions, in the declared order of value references."""
    from fmpy import read_model_description

    for version in VERSIONS:
        md = read_model_description(str(prebuilt_fmu("GyroPlant", version)))
        variables = [v for v in md.modelVariables if v.name != "time"]
        assert [v.name for v in variables] == [v.name for v in PLANT.variables]
        for v, decl in zip(variables, PLANT.variables, strict=True):
            assert v.valueReference == PLANT.value_reference(decl.name)
            assert (v.unit or None) == (None if decl.integer else decl.unit)
            assert v.causality == decl.causality
            if decl.min is not None:
                assert float(v.min) == decl.min
            if decl.causality != "output":
                assert float(v.start) == float(decl.start)


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("name", ["GyroPlant", "TwoToneDrive", "RateProfile"])
def test_fmpy_validate_and_fmutool_check_are_clean(version: int, name: str) -> None:
    import shutil
    import subprocess

    from fmpy.validation import validate_fmu

    fmu = prebuilt_fmu(name, version)
    assert validate_fmu(str(fmu)) == []
    fmutool = shutil.which("fmutool")
    if fmutool is None:
        pytest.skip("fmu-manipulation-toolbox's fmutool is not installed")
    proc = subprocess.run([fmutool, "-input", str(fmu), "-check"], capture_output=True,
                          text=True, timeout=120)
    text = proc.stdout + proc.stderr
    assert f"This FMU seems to be compliant with FMI-{version}.0." in text, text
    assert f"No semantic error against the FMI-{version} standard." in text, text
    assert "ERROR" not in text, text


@pytest.mark.parametrize("version", VERSIONS)
def test_every_platform_is_in_the_fmu_with_its_sources(version: int) -> None:
    """Binaries for linux x86_64 and aarch64, windows x86_64 and macOS (FMI 2.0: one
    universal darwin64 binary of x86_64 and arm64), each of its platform's format, and the
    C sources with what a host needs to compile them; the whole FMU under 1 MB."""
    import struct
    import zipfile

    fmu = prebuilt_fmu("GyroPlant", version)
    assert fmu.stat().st_size < 1 << 20
    with zipfile.ZipFile(fmu) as z:
        names = set(z.namelist())
        folders = (["linux64", "aarch64-linux", "win64", "darwin64"] if version == 2 else
                   ["x86_64-linux", "aarch64-linux", "x86_64-windows", "x86_64-darwin",
                    "aarch64-darwin"])
        suffix = {"win64": ".dll", "x86_64-windows": ".dll"}
        for folder in folders:
            ext = suffix.get(folder, ".dylib" if "darwin" in folder else ".so")
            data = z.read(f"binaries/{folder}/GyroPlant{ext}")
            if ext == ".so":
                machine = struct.unpack("<H", data[18:20])[0]
                assert data[:4] == b"\x7fELF" and machine == (183 if "aarch64" in folder
                                                               else 62)
            elif ext == ".dll":
                assert data[:2] == b"MZ"
            elif folder == "darwin64":
                assert struct.unpack(">II", data[:8]) == (0xCAFEBABE, 2)
            else:
                assert struct.unpack("<I", data[:4])[0] == 0xFEEDFACF
        for source in ("model.c", "fmi2.c", "fmi3.c", "instance.c", "instance_values.c",
                       "instance_states.c", "instance_internal.h", "gyro_structs.h",
                       "gyro_tables.h", "gyro_plant.c", "gyro_rng.c", "variables.h", "model.h"):
            assert f"sources/{source}" in names
        if version == 3:
            assert "sources/buildDescription.xml" in names


@pytest.mark.parametrize("version", VERSIONS)
def test_every_fmu_carries_its_readme_with_the_equations(version: int) -> None:
    """documentation/readme.md is the model's readme (fmu_src/models/<Model>/readme.md,
    which the docs site shows too), linked from documentation/index.html, and it quotes
    the patent's equation numbers."""
    import zipfile

    from gyro_fmu.fmu.native import NATIVE_INTERFACES, sources_root

    for name in NATIVE_INTERFACES:
        readme = (sources_root() / "models" / name / "readme.md").read_bytes()
        assert readme.startswith(f"# {name}\n".encode()) and b"\n## Equations\n" in readme
        with zipfile.ZipFile(prebuilt_fmu(name, version)) as z:
            assert z.read("documentation/readme.md") == readme
            assert b'href="readme.md"' in z.read("documentation/index.html")


def test_the_sources_in_the_fmu_compile_as_a_host_would(tmp_path) -> None:
    """A host that compiles the FMU from sources/ (FMI 2.0 SourceFiles) gets a library
    that reproduces the shipped binary's outputs."""
    import subprocess
    import zipfile

    from gyro_fmu.doctor.report import find_compiler

    compiler = find_compiler()
    if compiler is None:
        pytest.skip("needs a C compiler")
    fmu = prebuilt_fmu("GyroPlant", 2)
    with zipfile.ZipFile(fmu) as z:
        z.extractall(tmp_path / "fmu")
    sources = sorted((tmp_path / "fmu" / "sources").glob("*.c"))
    lib = tmp_path / "fmu" / "binaries" / "linux64" / "GyroPlant.so"
    lib.unlink()
    subprocess.run([compiler, "-std=c99", "-O2", "-ffp-contract=off", "-shared", "-fPIC",
                    "-o", str(lib), *map(str, sources), "-lm", "-lpthread"], check=True)
    p = PRESETS["park-horowitz"]
    n, h = 100, 5e-6
    t = np.arange(n) * h
    ux = np.array([drive_ux(1e-7, 4000.0, 1e-7, 1200.0, tk) for tk in t])
    run = NativeRun(fmu, unzipdir=tmp_path / "fmu")
    run.initialize()
    got = run.run(np.full(n, h), OUTPUTS, {"ux": ux, "Omega_z": np.ones(n)})
    run.fmu.terminate()
    run.fmu.freeInstance()
    assert np.array_equal(got, oracle_rows(p, np.full(n, h), ux, np.ones(n)))


@pytest.mark.parametrize("name", ["GyroPlant", "TwoToneDrive", "RateProfile"])
def test_the_pythonfmu_flavour_equals_the_native_fmu(pythonfmu_models, name: str) -> None:
    """The pythonfmu adapters call the same C core: noisy plant outputs, the drive and a
    sine rate are equal bit for bit to the native FMU's over 200 steps of 2-20 us."""
    rng = np.random.default_rng(5)
    steps = rng.uniform(2e-6, 20e-6, 200)
    t = np.concatenate([[0.0], np.cumsum(steps)[:-1]])
    settings = {"GyroPlant": dict(noise_x=1e-12, noise_vy=1e-8, seed=99, kxy=6e7, m=2e-7),
                "TwoToneDrive": dict(A1=0.3, f1=2500.0, A2=-0.2, f2=777.0),
                "RateProfile": dict(kind=4, amplitude=2.0, frequency=150.0, t_start=1e-4)}
    outputs = {"GyroPlant": OUTPUTS, "TwoToneDrive": ["ux", "uy"], "RateProfile": ["Omega_z"]}
    inputs = ({"ux": 1e-7 * np.sin(2 * np.pi * 4000 * t), "Omega_z": np.cos(600 * t)}
              if name == "GyroPlant" else {})
    rows = []
    for fmu in (prebuilt_fmu(name), pythonfmu_models / f"{name}.fmu"):
        run = NativeRun(fmu)
        run.initialize(**settings[name])
        rows.append(run.run(steps, outputs[name], inputs))
        run.close()
    assert np.array_equal(rows[0], rows[1])


def test_a_seed_outside_the_fmu_integer_is_refused_not_wrapped() -> None:
    """0.2.0 took --seed 4294967296 and ran the noise of seed 0 (32-bit wrap) while the
    summary recorded 4294967296: the scenario refuses what GyroPlant.fmu cannot hold."""
    from gyro_fmu.model.parameters import ParameterError
    from gyro_fmu.system.scenario import scenario

    for seed in (2**32, 2**31, -1, 1.5, True):
        with pytest.raises(ParameterError, match=r"not an integer in \[0, 2147483647\]"):
            scenario(seed=seed)
    assert scenario(seed=2**31 - 1).seed == 2**31 - 1


def test_signals_that_alias_or_vanish_are_refused_by_the_scenario() -> None:
    """0.2.0 took a 150 kHz rate at 5 us steps (RMS error 0.70 rad/s, exit 0), a sine of
    0 Hz and a drive tone of 0 Hz: the scenario refuses them with the numbers."""
    from gyro_fmu.model.parameters import ParameterError
    from gyro_fmu.system.scenario import scenario

    cases = {
        RateProfile(RateKind.sine, amplitude=1.0, frequency=150e3): "Nyquist frequency 100000",
        RateProfile(RateKind.sine, amplitude=1.0, frequency=0.0): "frequency 0 Hz is its offset",
    }
    for rate, why in cases.items():
        with pytest.raises(ParameterError, match=why):
            scenario(rate=rate)
    with pytest.raises(ParameterError, match="drive tone f1=120000 Hz is at or above"):
        scenario(drive=TwoToneDrive(1e-7, 120e3, 1e-7, 1200.0))
    with pytest.raises(ParameterError, match="drive tone f2=0 Hz adds nothing"):
        scenario(drive=TwoToneDrive(1e-7, 4000.0, 1e-7, 0.0))
    assert scenario(rate=RateProfile(RateKind.sine, amplitude=1.0, frequency=99e3))


@pytest.mark.parametrize("version", VERSIONS)
def test_an_aliasing_step_is_a_warning_from_the_fmu(version: int) -> None:
    """An FMU does not know the host's step before it comes: a step that aliases the
    rate's sine is logged as a warning with the numbers (fmi2Warning), once per size."""
    run = NativeRun(prebuilt_fmu("RateProfile", version))
    run.initialize(kind=4, amplitude=1.0, frequency=150e3)
    run.run(np.full(3, 5e-6), ["Omega_z"])
    warned = [m for s, m in run.messages if s == 1]
    assert len(warned) == 1 and "Nyquist frequency 100000 Hz of the 5e-06 s" in warned[0]
    run.run(np.full(3, 2e-6), ["Omega_z"], start_time=1.5e-5)
    assert len([m for s, m in run.messages if s == 1]) == 1  # 2 us carries 150 kHz
    run.close()


def test_the_sources_built_are_those_beside_the_imported_package(monkeypatch, tmp_path) -> None:
    """sources_root prefers the fmu_src/ of the checkout (or the installation) that
    gyro_fmu was imported from over what the import system maps gyro_fmu.fmu_src to: an
    editable install maps it to its own checkout, and a git worktree imported first built
    the first checkout's C sources (an A/B of this session's was wrong by it)."""
    import importlib.machinery
    import importlib.util

    from gyro_fmu.fmu import sources

    (tmp_path / "fmu_src" / "core").mkdir(parents=True)  # another checkout's sources

    elsewhere = importlib.machinery.ModuleSpec("gyro_fmu.fmu_src", None, is_package=True)
    elsewhere.submodule_search_locations = [str(tmp_path / "fmu_src")]
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: elsewhere)
    assert sources.sources_root() == sources.REPO_SOURCES
    assert (sources.REPO_SOURCES / "core" / "gyro_observer.c").is_file()
