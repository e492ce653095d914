"""Inspects what python/build-wheels.sh made, without installing it (so a wheel for another architecture too).

    python python/inspect_wheel.py WHEEL ARCH POLICY
        The wheel's files, its extension's ELF machine, the shared libraries it needs (each allowed by the manylinux
        policy), its newest glibc symbol version (at most the policy's) and its size.
    auditwheel show --json WHEEL | python python/inspect_wheel.py --auditwheel TAG
        auditwheel's verdict: consistent with TAG (manylinux_2_28_x86_64), no external shared library, no
        unsupported instruction set.
    python python/inspect_wheel.py --metadata VERSION SDIST WHEEL...
        The sdist's PKG-INFO and every wheel's METADATA: Cargo.toml's version and the same name, licence, summary,
        classifiers, project URLs and requirements.
Exits non-zero, saying why, when a check fails. Uses binutils' readelf, which reads any architecture's ELF.
"""

import email.parser
import json
import re
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from pathlib import Path

MACHINES = {"x86_64": "Advanced Micro Devices X86-64", "aarch64": "AArch64"}
# What a manylinux wheel may link (PEP 600's policies list these for every architecture; auditwheel checks the
# policy's own list too). meshvox's extension needs only the C library's parts.
ALLOWED = {"libc.so.6", "libm.so.6", "libdl.so.2", "libpthread.so.0", "librt.so.1", "libgcc_s.so.1",
           "ld-linux-x86-64.so.2", "ld-linux-aarch64.so.1"}
FILES = {"meshvox/__init__.py", "meshvox/_native.abi3.so", "meshvox/_native.pyi", "meshvox/py.typed"}
FIELDS = ["Name", "Version", "License", "Summary", "Requires-Python", "Classifier", "Project-URL", "Requires-Dist",
          "Provides-Extra"]


def fail(message):
    sys.exit(f"python/inspect_wheel.py: {message}")


def readelf(flag, path):
    return subprocess.run(["readelf", flag, "-W", path], check=True, capture_output=True, text=True).stdout


def inspect(wheel, arch, policy):
    names = set(zipfile.ZipFile(wheel).namelist())
    if not FILES <= names:
        fail(f"{wheel} lacks {sorted(FILES - names)}")
    with tempfile.TemporaryDirectory() as tmp:
        so = zipfile.ZipFile(wheel).extract("meshvox/_native.abi3.so", tmp)
        machine = re.search(r"Machine:\s*(.*)", readelf("-h", so)).group(1).strip()
        needed = re.findall(r"\(NEEDED\)\s+Shared library: \[(.*)\]", readelf("-d", so))
        glibc = re.findall(r"Name: GLIBC_([0-9.]+)", readelf("-V", so))
        size = Path(so).stat().st_size
    if machine != MACHINES[arch]:
        fail(f"{wheel}'s extension is for {machine}, not {arch}")
    if not set(needed) <= ALLOWED:
        fail(f"{wheel}'s extension needs {sorted(set(needed) - ALLOWED)}, outside the manylinux policy")
    newest = max(glibc, key=lambda v: tuple(map(int, v.split("."))))
    most = tuple(map(int, policy.removeprefix("manylinux_").split("_")))
    if tuple(map(int, newest.split("."))) > most:
        fail(f"{wheel} needs glibc {newest}, newer than {policy}")
    print(f"{Path(wheel).name}: {Path(wheel).stat().st_size:,} bytes ({size:,} unpacked extension); {machine}; "
          f"needs {', '.join(needed)}; newest glibc symbol {newest}")


def audit(report, tag):
    verdict = json.loads(report)
    if verdict.get("overall_tag") != tag or verdict.get("external_libs") or verdict.get("unsupported_isa") \
            or verdict.get("pyfpe") or verdict.get("ucs2"):
        fail(f"auditwheel: {verdict.get('wheel')} is not a clean {tag} wheel: {json.dumps(verdict)}")
    print(f"auditwheel: {verdict['wheel']} is consistent with {tag}, no external shared library")


def fields(text):
    message = email.parser.Parser().parsestr(text)
    return {field: sorted(message.get_all(field) or []) for field in FIELDS}


def metadata(version, sdist, wheels):
    with tarfile.open(sdist) as tar:
        member = next(m for m in tar.getmembers() if m.name.count("/") == 1 and m.name.endswith("/PKG-INFO"))
        expected = fields(tar.extractfile(member).read().decode())
    if expected["Version"] != [version]:
        fail(f"{sdist} says version {expected['Version']}, Cargo.toml {version}")
    for field in ("License", "Classifier", "Project-URL", "Summary"):
        if not expected[field]:
            fail(f"{sdist} has no {field}")
    for wheel in wheels:
        archive = zipfile.ZipFile(wheel)
        name = next(n for n in archive.namelist() if n.endswith(".dist-info/METADATA"))
        got = fields(archive.read(name).decode())
        for field in FIELDS:
            if got[field] != expected[field]:
                fail(f"{wheel}'s {field} is {got[field]}, the sdist's {expected[field]}")
    print(f"{Path(sdist).name}: {Path(sdist).stat().st_size:,} bytes; version {version}, "
          f"{len(expected['Classifier'])} classifiers, {len(expected['Project-URL'])} project URLs, "
          f"the same in {len(wheels)} wheel(s)")


if __name__ == "__main__":
    if sys.argv[1] == "--auditwheel":
        audit(sys.stdin.read(), sys.argv[2])
    elif sys.argv[1] == "--metadata":
        metadata(sys.argv[2], sys.argv[3], sys.argv[4:])
    else:
        inspect(*sys.argv[1:4])
