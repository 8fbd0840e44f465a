"""`pip install .` (pyproject.toml, python/build_backend/stroma_build.py) into a fresh virtual
environment, as a user would, then `import stroma` from there — not from the build tree.

Asserted: pip builds and installs the wheel offline (no index is reachable: --no-index); the
installed module is the venv's (not PYTHONPATH's); it steps the scenario shipped in the package
exactly as the build tree's module does (same bits); `pip uninstall` removes it. The backend
answers pip's metadata hook without building, and reports the build's progress on the terminal
(here a file: STROMA_BUILD_PROGRESS), Ninja's [k/n] counter with the elapsed time.
Usage (ctest python.pip_install): check_pip_install.py SOURCE_DIR BUILD_DIR
The build directory is reused (config setting build-dir), so nothing is compiled twice.
"""
import hashlib
import io
import os
import pathlib
import subprocess
import sys
import tempfile

PROBE = """
import hashlib, os, stroma, stroma.env
print(stroma.__file__)
sim = stroma.Simulation(os.path.join(stroma.env.DATA_DIR, "regression", "liver_probe_damage.yaml"))
sim.step(300)
print(hashlib.sha256(sim.positions.tobytes()).hexdigest(), sim.steps)
"""


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"FAILED: {' '.join(cmd)}\n{r.stdout}\n{r.stderr}")
    return r.stdout


def check_backend_hooks(source):
    """The metadata hook builds nothing; the progress lines follow Ninja's counter."""
    sys.path.insert(0, os.path.join(source, "python", "build_backend"))
    import stroma_build
    with tempfile.TemporaryDirectory() as tmp:
        name = stroma_build.prepare_metadata_for_build_wheel(tmp)
        meta = (pathlib.Path(tmp) / name / "METADATA").read_text()
        assert name.endswith(".dist-info") and "Name: stroma" in meta and "Requires-Dist: numpy" in meta, meta
        assert sorted(os.listdir(tmp)) == [name], "the metadata hook made nothing but the dist-info"
    stream = io.StringIO()
    fake_ninja = ["sh", "-c", "echo '[1/4] Building a'; sleep 2.2; echo '[3/4] Building b'; echo '[4/4] Linking'"]
    stroma_build._run(fake_ninja, stream)
    text = stream.getvalue()
    assert "compiling 3/4 (75 %), 0 min 2 s" in text and "compiled 4 steps" in text, text


def main(source, build):
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    check_backend_hooks(source)
    with tempfile.TemporaryDirectory() as tmp:
        venv = os.path.join(tmp, "venv")
        # System site-packages: numpy comes from Debian's python3-numpy, not from PyPI.
        run([sys.executable, "-m", "venv", "--system-site-packages", venv])
        py = os.path.join(venv, "bin", "python")
        progress = os.path.join(tmp, "progress.txt")
        out = run([py, "-m", "pip", "install", "--no-index", "--config-settings", f"build-dir={build}", source],
                  env=dict(clean, STROMA_BUILD_PROGRESS=progress), cwd=tmp)
        assert "Successfully installed stroma" in out, out
        shown = open(progress).read()
        assert "stroma_build: building the module in" in shown, f"no progress on the terminal: {shown!r}"
        lines = run([py, "-c", PROBE], env=clean, cwd=tmp).split()
        assert lines[0].startswith(venv), f"imported {lines[0]}, not the venv's package"
        ref = run([sys.executable, "-c", PROBE], env=dict(clean, PYTHONPATH=os.path.join(build, "python")), cwd=tmp).split()
        assert ref[0].startswith(os.path.join(build, "python")), ref[0]
        assert lines[1:] == ref[1:], f"installed {lines[1:]} != build tree {ref[1:]}"
        run([py, "-m", "pip", "uninstall", "-y", "stroma"], env=clean, cwd=tmp)
        gone = subprocess.run([py, "-c", "import stroma"], env=clean, cwd=tmp, capture_output=True)
        assert gone.returncode != 0, "uninstalled, yet importable"
    print("pip install . -> import stroma: ok (same bits as the build tree; uninstall removes it)")


if __name__ == "__main__":
    main(*sys.argv[1:3])
