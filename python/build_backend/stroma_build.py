"""`pip install .` for Stroma: a PEP 517 build backend that builds the module with the project's
own CMake and packs it as a wheel (docs/PYTHON.md, "Install").

Why this file instead of a library: the CMake backends (scikit-build-core, py-build-cmake) are not
Debian 12 packages, and setuptools would have to come from PyPI into pip's isolated build
environment — a network fetch on every install. This backend needs nothing but the standard
library and the tools scripts/setup.sh installs (CMake, Ninja, the compilers), so `pip install .`
works offline. It is in-tree (pyproject.toml's backend-path) and only builds what the module needs.

The build directory is `build/pip` in the source tree, kept between installs (a second install
only rebuilds what changed). config_settings: `build-dir=DIR`, `build-type=Release|...`,
`jobs=N`.

Progress: pip shows a build backend's output only with `pip install -v`; a first build takes
minutes. So the metadata hook answers at once (no build behind "Preparing metadata"), and while
the module compiles, a progress line ("stroma_build: compiling 37/107 (35 %), 2 min 10 s") goes
to the terminal pip runs in (/dev/tty; STROMA_BUILD_PROGRESS=FILE sends it to FILE instead,
=none switches it off), at most every 2 s, besides the full log on stderr (pip -v).
"""
import base64
import hashlib
import os
import pathlib
import re
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import time
import zipfile

SOURCE = pathlib.Path(__file__).resolve().parents[2]
NAME = "stroma"


def _version():
    text = (SOURCE / "CMakeLists.txt").read_text()
    m = re.search(r"project\(\s*stroma\s+VERSION\s+([0-9.]+)", text, re.IGNORECASE)
    if not m:
        raise RuntimeError("CMakeLists.txt: project(stroma VERSION x.y.z) not found")
    return m.group(1)


def _metadata():
    readme = "Soft-tissue FEM for interactive surgical simulation, from Python. See docs/PYTHON.md."
    return (f"Metadata-Version: 2.1\nName: {NAME}\nVersion: {_version()}\n"
            "Summary: Stroma: soft-tissue FEM for interactive surgical simulation (the headless engine)\n"
            "License: the package data include SOFA's liver mesh, LGPL 2.1 (stroma/data/meshes/README.md)\n"
            "Requires-Python: >=3.9\nRequires-Dist: numpy\n"
            f"Description-Content-Type: text/plain\n\n{readme}\n")


def _tag():
    impl = f"cp{sys.version_info.major}{sys.version_info.minor}"
    plat = re.sub(r"[^A-Za-z0-9]", "_", sysconfig.get_platform())
    return f"{impl}-{impl}-{plat}"


def _interpreter():
    """The interpreter the module is for: a virtual environment's base Python (same ABI; CMake
    finds its headers and Debian's site-packages layout there)."""
    return getattr(sys, "_base_executable", None) or sys.executable


def _setting(config_settings, key, default):
    return (config_settings or {}).get(key, default)


def _progress_stream():
    """Where progress lines go: the terminal pip runs in (pip hides the backend's own output)."""
    target = os.environ.get("STROMA_BUILD_PROGRESS", "/dev/tty")
    if target == "none":
        return None
    try:
        return open(target, "a")
    except OSError:  # no terminal (CI, a pipe): the log on stderr is all there is
        return None


def _run(cmd, progress=None):
    """Runs cmd with its output on stderr; with `progress` (a stream), Ninja's [k/n] counter and
    the elapsed time on it, at most every 2 s."""
    print("stroma_build:", " ".join(str(c) for c in cmd), file=sys.stderr, flush=True)
    if progress is None:
        subprocess.run([str(c) for c in cmd], check=True, stdout=sys.stderr)
        return
    start = last = time.monotonic()
    step = None
    with subprocess.Popen([str(c) for c in cmd], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          bufsize=1) as p:
        for line in p.stdout:
            sys.stderr.write(line)
            m = re.match(r"\[(\d+)/(\d+)\]", line)
            if m:
                step = (int(m.group(1)), int(m.group(2)))
            now = time.monotonic()
            if step and now - last >= 2.0:
                last = now
                k, n = step
                el = int(now - start)
                progress.write(f"stroma_build: compiling {k}/{n} ({100 * k // n} %), {el // 60} min {el % 60} s\n")
                progress.flush()
        rc = p.wait()
    if step:
        el = int(time.monotonic() - start)
        progress.write(f"stroma_build: compiled {step[1]} steps in {el // 60} min {el % 60} s\n")
        progress.flush()
    if rc != 0:
        raise subprocess.CalledProcessError(rc, [str(c) for c in cmd])


def _build_module(config_settings):
    """Configures and builds the _stroma target; returns the package directory CMake filled."""
    build = pathlib.Path(_setting(config_settings, "build-dir", SOURCE / "build" / "pip"))
    if not build.is_absolute():
        build = SOURCE / build
    cmake = shutil.which("cmake")
    if not cmake:
        raise RuntimeError("cmake is not installed: run scripts/setup.sh (or apt install cmake ninja-build)")
    gen = ["-G", "Ninja"] if shutil.which("ninja") and not (build / "CMakeCache.txt").exists() else []
    _run([cmake, "-S", SOURCE, "-B", build, *gen,
          f"-DCMAKE_BUILD_TYPE={_setting(config_settings, 'build-type', 'Release')}",
          "-DSTROMA_PYTHON=ON", f"-DPython3_EXECUTABLE={_interpreter()}"])
    jobs = str(_setting(config_settings, "jobs", os.cpu_count() or 1))
    progress = _progress_stream()
    try:
        if progress:
            progress.write(f"stroma_build: building the module in {build} with {jobs} jobs "
                           "(minutes the first time; pip install -v shows the compiler's log)\n")
            progress.flush()
        _run([cmake, "--build", build, "--target", "_stroma", "--parallel", jobs], progress)
    finally:
        if progress:
            progress.close()
    pkg = build / "python" / NAME
    if not any(pkg.glob("_stroma*.so")):
        raise RuntimeError(f"the build made no module in {pkg} (is python3-dev installed? scripts/setup.sh)")
    return pkg


def _record_line(arcname, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{arcname},sha256={digest},{len(data)}"


# --- PEP 517 hooks -------------------------------------------------------------------------------

def get_requires_for_build_wheel(config_settings=None):
    return []


def get_requires_for_build_sdist(config_settings=None):
    return []


def prepare_metadata_for_build_wheel(metadata_directory, config_settings=None):
    """The wheel's metadata without building it (pip's "Preparing metadata" is then instant)."""
    dist_info = pathlib.Path(metadata_directory) / f"{NAME}-{_version()}.dist-info"
    dist_info.mkdir(parents=True, exist_ok=True)
    (dist_info / "METADATA").write_text(_metadata())
    (dist_info / "top_level.txt").write_text(f"{NAME}\n")
    return dist_info.name


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    pkg = _build_module(config_settings)
    dist_info = f"{NAME}-{_version()}.dist-info"
    wheel_name = f"{NAME}-{_version()}-{_tag()}.whl"
    files = []
    for path in sorted(pkg.rglob("*")):
        if path.is_file() and "__pycache__" not in path.parts:
            files.append((f"{NAME}/{path.relative_to(pkg).as_posix()}", path.read_bytes()))
    files.append((f"{dist_info}/METADATA", _metadata().encode()))
    files.append((f"{dist_info}/WHEEL", (f"Wheel-Version: 1.0\nGenerator: stroma_build\nRoot-Is-Purelib: false\n"
                                          f"Tag: {_tag()}\n").encode()))
    files.append((f"{dist_info}/top_level.txt", f"{NAME}\n".encode()))
    record = [_record_line(a, d) for a, d in files] + [f"{dist_info}/RECORD,,"]
    files.append((f"{dist_info}/RECORD", ("\n".join(record) + "\n").encode()))
    os.makedirs(wheel_directory, exist_ok=True)
    with zipfile.ZipFile(os.path.join(wheel_directory, wheel_name), "w", zipfile.ZIP_DEFLATED) as z:
        for arcname, data in files:
            info = zipfile.ZipInfo(arcname, date_time=(2026, 1, 1, 0, 0, 0))
            info.external_attr = (0o755 if arcname.endswith(".so") else 0o644) << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, data)
    print(f"stroma_build: wrote {wheel_name} ({len(files)} files)", file=sys.stderr)
    return wheel_name


def build_sdist(sdist_directory, config_settings=None):
    """The source tree as git tracks it (or, outside a clone, without build directories)."""
    base = f"{NAME}-{_version()}"
    try:
        out = subprocess.run(["git", "-C", str(SOURCE), "ls-files", "-z"], check=True, capture_output=True).stdout
        names = [n for n in out.decode().split("\0") if n]
    except (OSError, subprocess.CalledProcessError):
        names = [str(p.relative_to(SOURCE)) for p in SOURCE.rglob("*")
                 if p.is_file() and not any(part.startswith(("build", ".git")) for part in p.relative_to(SOURCE).parts)]
    name = f"{base}.tar.gz"
    os.makedirs(sdist_directory, exist_ok=True)
    with tarfile.open(os.path.join(sdist_directory, name), "w:gz") as t:
        for n in names:
            if (SOURCE / n).is_file():
                t.add(SOURCE / n, arcname=f"{base}/{n}")
        meta = (SOURCE / "build" / "PKG-INFO")
        meta.parent.mkdir(exist_ok=True)
        meta.write_text(_metadata())
        t.add(meta, arcname=f"{base}/PKG-INFO")
    return name
