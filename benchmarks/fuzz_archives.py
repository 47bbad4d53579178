"""Fuzz `validate` with mutated FMU archives and references (issue 16, defect 4).

Each trial: a mutated copy of a built FMU, validated in a forked child with its cwd in
a fresh empty folder and TMPDIR in another; checks: no uncaught exception or signal,
nothing written outside TMPDIR (the trial folder is snapshotted, and traversal sources
aim at a canary path in it), and no pass on a mutation classified damaging up front.
Every 10th trial also goes through the `gyro-fmu validate` CLI in a subprocess.
Usage: python benchmarks/fuzz_archives.py MODELS_DIR [N=200]
"""

from __future__ import annotations

import collections
import os
import random
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

LS = "extra/org.fmi-standard.fmi-ls-ref"
KINDS = ["flip", "truncate", "remove", "replace", "traversal", "absolute", "huge", "duplicate",
         "rows", "value", "nan", "rename", "drop", "shift", "crlf"]


def mutate(rng, kind, src: Path, dst: Path, canary: Path) -> bool:
    """Write the mutated archive; return True if the mutation damages the reference or
    the archive (must FAIL), False if it leaves it intact (may pass)."""
    raw = src.read_bytes()
    if kind == "flip":
        b = bytearray(raw)
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
        dst.write_bytes(bytes(b))
        return False  # may hit a zip field zipfile ignores: either answer is fine
    if kind == "truncate":
        dst.write_bytes(raw[:rng.randrange(len(raw))])
        return True
    model = src.stem
    out, man = f"{LS}/{model}_out.csv", f"{LS}/fmi-ls-manifest.xml"
    with zipfile.ZipFile(src) as z:
        members = {i.filename: z.read(i) for i in z.infolist()}
    damaging = True
    csv = members[out].decode().splitlines()
    if kind == "remove":
        del members[rng.choice([out, man, "modelDescription.xml"])]
    elif kind == "replace":
        members[rng.choice([out, man, "modelDescription.xml"])] = os.urandom(200)
    elif kind in ("traversal", "absolute"):
        target = str(canary) if kind == "absolute" else "../" * rng.randint(1, 12) + str(
            canary).lstrip("/")
        members[man] = members[man].replace(f'source="{model}_out.csv"'.encode(),
                                            f'source="{target}"'.encode())
        members[f"{LS}/{target}"] = members[out]
    elif kind == "huge":
        extra = b"<Related " + b"a" * 10**6 + b'="1" source="x.csv" role="result"/>'
        members[man] = members[man].replace(b"</fmiReferences>", extra + b"</fmiReferences>")
    elif kind == "duplicate":
        extra = f'<Related source="{model}_out.csv" role="result"/>' * 2
        members[man] = members[man].replace(b"</fmiReferences>",
                                            extra.encode() + b"</fmiReferences>")
    elif kind == "rows":
        for _ in range(rng.randint(1, 5)):
            del csv[rng.randrange(1, len(csv))]
    elif kind == "value":
        i, cells = rng.randrange(2, len(csv)), None
        cells = csv[i].split(",")
        j = rng.randrange(1, len(cells))
        cells[j] = repr(float(cells[j]) * 1.5 + 1.0)  # far beyond a 1e-6 band
        csv[i] = ",".join(cells)
    elif kind == "nan":
        i = rng.randrange(1, len(csv))
        csv[i] = csv[i].rsplit(",", 1)[0] + ",nan"
    elif kind == "rename":
        csv[0] = csv[0].replace('"time",', '"time","zz_', 1)
    elif kind == "drop":
        csv = [line.rsplit(",", 1)[0] for line in csv]
    elif kind == "shift":
        csv[1:] = [",".join([repr(float(c.split(",")[0]) + 1e-3), *c.split(",")[1:]])
                   for c in csv[1:]]
    elif kind == "crlf":
        damaging = False
    if kind in ("rows", "value", "nan", "rename", "drop", "shift", "crlf"):
        members[out] = ("\r\n" if kind == "crlf" else "\n").join(csv).encode() + b"\n"
    with zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return damaging


def snapshot(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def trial(fmu: Path, work: Path) -> int:
    """Validate in a forked child: its exit code (0 pass, 1 fail, 3 uncaught, <0 signal)."""
    pid = os.fork()
    if pid == 0:
        code = 3
        try:
            os.chdir(work / "cwd")
            os.environ["TMPDIR"] = tempfile.tempdir = str(work / "tmp")
            from gyro_fmu.fmu.validate import validate_files
            code = validate_files([str(fmu)], write=lambda s: None)
        except BaseException:
            import traceback
            traceback.print_exc()
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    return -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)


def main() -> None:
    models, n = Path(sys.argv[1]), int(sys.argv[2]) if len(sys.argv) > 2 else 200
    rng = random.Random(16)
    table = collections.defaultdict(collections.Counter)
    with tempfile.TemporaryDirectory() as root_s:
        root = Path(root_s)
        for i in range(n):
            kind = KINDS[i % len(KINDS)]
            src = models / (rng.choice(["GyroPlant", "RateProfile", "TwoToneDrive",
                                        "GyroResonator"]) + ".fmu")
            work = root / f"t{i}"
            for d in ("cwd", "tmp", "in"):
                (work / d).mkdir(parents=True)
            fmu, canary = work / "in" / src.name, work / "CANARY.csv"
            damaging = mutate(rng, kind, Path(src), fmu, canary)
            before = snapshot(root)
            code = trial(fmu, work)
            if i % 10 == 0:
                env = dict(os.environ, TMPDIR=str(work / "tmp"))
                exe = str(Path(sys.executable).parent / "gyro-fmu")
                cli = subprocess.run([exe, "validate", str(fmu)],
                                     cwd=work / "cwd", env=env, capture_output=True, timeout=300)
                table[kind]["cli"] += 1
                if cli.returncode not in (0, 1) or b"Traceback" in cli.stderr:
                    table[kind]["crash"] += 1
            after = {p for p in snapshot(root) - before if not p.startswith(f"t{i}/tmp")}
            c = table[kind]
            c["trials"] += 1
            c["pass" if code == 0 else "fail" if code == 1 else "crash"] += 1
            c["outside"] += bool(after or canary.exists())
            c["damaged-pass"] += damaging and code == 0
    cols = ["trials", "pass", "fail", "crash", "outside", "damaged-pass", "cli"]
    print(f"{'kind':<10}" + "".join(f"{c:>13}" for c in cols))
    for kind in KINDS:
        print(f"{kind:<10}" + "".join(f"{table[kind][c]:>13}" for c in cols))
    print(f"{'total':<10}" + "".join(f"{sum(t[c] for t in table.values()):>13}" for c in cols))


if __name__ == "__main__":
    main()
