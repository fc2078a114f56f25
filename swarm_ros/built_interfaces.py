"""Interface packages without a PyPI wheel, built here: ``tf2_msgs`` and ``simulation_interfaces``.

Their definitions are in ``interfaces/`` (copied unchanged from their upstream repositories; its
README names the commits).  :func:`ensure` builds them once with the ROS 2 rosidl generators
(``rosidl_generate_interfaces`` through ``ament_cmake``, both PyPI wheels), CMake and the C
compiler, and installs them into the virtual environment's prefix beside the wheels' packages
(``lib/``, ``share/``, ``site-packages``), where the wheels' loader path already looks.  A stamp
(the SHA-256 of the definitions) in ``share/<package>/`` says what was built; a changed
definition is built again.  Builds are serialised by a lock file, so parallel test workers and
commands wait for one build instead of racing.

Without a C compiler (or with a prefix that cannot be written), nothing is built: the features
that need these types (``/tf`` and the ``simulation_interfaces`` services) are off, and
:func:`ensure` says in one line what is missing.

``swarm-interfaces`` builds them up front (``--check`` only reports).
"""

from __future__ import annotations

import argparse
import fcntl
import hashlib
import importlib
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from swarm_common.paths import ROOT

SOURCES = ROOT / "interfaces"
PACKAGES = ("tf2_msgs", "simulation_interfaces")
"""Built in this order; each names the message or service whose import proves it built."""
_PROBES = {"tf2_msgs": ("tf2_msgs.msg", "TFMessage"),
           "simulation_interfaces": ("simulation_interfaces.srv", "GetSimulatorFeatures")}
STAMP = "swarm_source.sha256"
BUILD_TIMEOUT_S = 1800  # [s] wall, one package; a build here takes ~10 s and ~70 s


@dataclass(frozen=True)
class Availability:
    """What :func:`ensure` found: the packages importable, and why the others are not."""

    ready: frozenset[str]
    missing: str | None = None
    """One line naming what is missing (None when every package is ready)."""

    def has(self, package: str) -> bool:
        return package in self.ready


def prefix() -> Path:
    """The install prefix: the running Python's environment (its ``lib/`` is on the wheels'
    library path, set by ``ros_wheels_bootstrapper``)."""
    return Path(sys.prefix)


def source_digest(package: str) -> str:
    """SHA-256 of ``interfaces/<package>`` and the shared CMake helper, hex."""
    h = hashlib.sha256()
    files = sorted(p for p in (SOURCES / package).rglob("*") if p.is_file())
    for p in [*files, SOURCES / "wheel_targets.cmake"]:
        h.update(str(p.relative_to(SOURCES)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()


def _stamp_path(package: str) -> Path:
    return prefix() / "share" / package / STAMP


def importable(package: str) -> bool:
    """Whether ``package``'s probe type imports and its type support loads."""
    module, name = _PROBES[package]
    try:
        mod = __import__(module, fromlist=[name])
        cls = getattr(mod, name)
        cls.__class__.__import_type_support__()
    except Exception:  # noqa: BLE001 - any failure means "not built (or broken)"
        return False
    return True


def built(package: str) -> bool:
    """Built from today's definitions (stamp matches) and importable."""
    stamp = _stamp_path(package)
    return (stamp.is_file() and stamp.read_text().strip() == source_digest(package)
            and importable(package))


def missing_prerequisite() -> str | None:
    """What the build lacks, in words, or None."""
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    cxx = os.environ.get("CXX") or shutil.which("c++") or shutil.which("g++")
    if not cc or not cxx:
        return "no C/C++ compiler (cc, c++) on PATH: install gcc and g++ (Debian: build-essential)"
    if not _cmake():
        return "no cmake (the 'cmake' PyPI package is a dependency: reinstall the project)"
    if sysconfig.get_paths().get("include") is None or not Path(
            sysconfig.get_paths()["include"], "Python.h").is_file():
        return "no Python headers (Python.h) for this interpreter"
    if not os.access(prefix(), os.W_OK):
        return f"{prefix()} is not writable"
    return None


def _cmake() -> str | None:
    here = Path(sys.executable).parent / "cmake"
    return str(here) if here.is_file() else shutil.which("cmake")


def _env() -> dict[str, str]:
    env = dict(os.environ)
    pre = str(prefix())
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env["AMENT_PREFIX_PATH"] = os.pathsep.join(
        p for p in (pre, env.get("AMENT_PREFIX_PATH", "")) if p)
    env["CMAKE_PREFIX_PATH"] = os.pathsep.join(
        p for p in (pre, env.get("CMAKE_PREFIX_PATH", "")) if p)
    return env


def build(package: str, log) -> None:
    """Configure, build and install ``package`` into :func:`prefix`.

    Args:
        package: one of :data:`PACKAGES`.
        log: a text file receiving the tools' output.

    Raises:
        RuntimeError: a step failed (the message names it; the output is in ``log``).
    """
    cmake, env, pre = _cmake(), _env(), str(prefix())
    with tempfile.TemporaryDirectory(prefix=f"swarm-{package}-") as tmp:
        steps = [
            [cmake, "-S", str(SOURCES / package), "-B", tmp, f"-DCMAKE_INSTALL_PREFIX={pre}",
             f"-DCMAKE_PREFIX_PATH={pre}", f"-DPython3_EXECUTABLE={sys.executable}",
             "-DBUILD_TESTING=OFF", "-DCMAKE_BUILD_TYPE=Release"],
            [cmake, "--build", tmp, "-j", str(max(1, os.cpu_count() or 1))],
            [cmake, "--install", tmp],
        ]
        for cmd in steps:
            log.write(f"$ {' '.join(cmd)}\n")
            log.flush()
            done = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, env=env,
                                  timeout=BUILD_TIMEOUT_S, check=False)
            if done.returncode != 0:
                raise RuntimeError(f"{package}: '{' '.join(cmd[:2])}' failed "
                                   f"(exit {done.returncode})")
    _stamp_path(package).write_text(source_digest(package) + "\n")


def log_path() -> Path:
    return prefix() / "share" / "swarm_interfaces_build.log"


def _failed_path() -> Path:
    return prefix() / "share" / ".swarm_interfaces_failed"


def _digests(packages) -> str:
    return " ".join(source_digest(p) for p in packages)


def ensure(say=None, packages=PACKAGES, retry: bool = False) -> Availability:
    """Build whichever of ``packages`` is not built from today's definitions.

    A build that failed is not tried again for the same definitions (every command of a run
    would otherwise spend its start on it) unless ``retry``: ``swarm-interfaces`` retries.

    Args:
        say: called with one line before a build starts and when one fails (default: stderr).
        packages: which to make available.
        retry: build even if the last build of these definitions failed.

    Returns:
        The packages importable now, and what is missing for the others.
    """
    if say is None:
        def say(line: str) -> None:
            print(line, file=sys.stderr, flush=True)
    todo = [p for p in packages if not built(p)]
    if not todo:
        return Availability(frozenset(packages))
    why = missing_prerequisite()
    failed = _failed_path()
    if why is None and not retry and failed.is_file() and (
            failed.read_text().strip() == _digests(todo)):
        why = f"their last build failed (log: {log_path()}; `swarm-interfaces` tries again)"
    if why is None:
        lock_path = prefix() / "share" / ".swarm_interfaces.lock"
        with open(lock_path, "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # another process may be building them: wait
            todo = [p for p in todo if not built(p)]
            if todo:
                say(f"building {', '.join(todo)} from their definitions (once, about a "
                    f"minute; log: {log_path()})")
                t0 = time.monotonic()
                with open(log_path(), "w") as log:
                    for p in todo:
                        try:
                            build(p, log)
                        except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
                            why = f"the build failed: {exc} (log: {log_path()})"
                            failed.write_text(_digests(todo) + "\n")
                            break
                importlib.invalidate_caches()  # site-packages gained packages
                if why is None:
                    failed.unlink(missing_ok=True)
                    say(f"built {', '.join(todo)} in {time.monotonic() - t0:.0f} s")
    ready = frozenset(p for p in packages if p not in todo or built(p))
    if why is not None:
        say(f"warning: {', '.join(p for p in packages if p not in ready)} not available: {why}; "
            "/tf and the simulation_interfaces services are off")
    return Availability(ready, why)


def main(argv=None) -> int:
    """Entry point of ``swarm-interfaces``."""
    parser = argparse.ArgumentParser(
        prog="swarm-interfaces",
        description="Build the interface packages without a PyPI wheel (tf2_msgs, "
                    "simulation_interfaces) into this virtual environment with the rosidl "
                    "generators and the C compiler. Commands that need them build them on "
                    "first use; this does it up front.")
    parser.add_argument("--check", action="store_true",
                        help="only report which are built (exit 1 if any is not)")
    args = parser.parse_args(argv)
    if args.check:
        status = {p: built(p) for p in PACKAGES}
        for p, ok in status.items():
            print(f"{p}: {'built' if ok else 'not built'}")
        why = missing_prerequisite()
        if why is not None and not all(status.values()):
            print(f"cannot build: {why}")
        return 0 if all(status.values()) else 1
    result = ensure(say=lambda line: print(line, flush=True), retry=True)
    for p in PACKAGES:
        print(f"{p}: {'built' if result.has(p) else 'not available'}")
    return 0 if result.missing is None else 1


if __name__ == "__main__":
    sys.exit(main())
