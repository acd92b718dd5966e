#!/usr/bin/env python3
"""Boot a user-mode Linux guest with a bounded timeout; find or install the UML kernel first.

Two facts about UML on current hosts shape this module:

* **Large XSAVE state.** UML 6.1/6.12 restores a guest process's vector registers with
  ``PTRACE_SETREGSET(NT_X86_XSTATE)`` using a fixed 832-byte buffer, and the host kernel insists on
  the host's full XSAVE size (10-11 KiB with AMX, 2.7 KiB with AVX-512), so the first guest process
  dies with "userspace - ptrace set fp regs failed, errno = 14". We start UML under a tiny seccomp
  filter that fails ``PTRACE_{GET,SET}REGSET(NT_X86_XSTATE)`` with EIO; UML then falls back to the
  FXSAVE path (x87 + SSE registers only).
* **Only SSE state survives.** With that fallback the AVX/AVX-512 register state of guest processes
  is not preserved (glibc's AVX2/EVEX string functions visibly break: ``printf`` prints "%s"), so
  every guest process is told to stay on SSE code paths: ``GLIBC_TUNABLES`` masks AVX for glibc's
  ifuncs, ``NPY_DISABLE_CPU_FEATURES`` disables numpy's AVX dispatch targets and
  ``OPENBLAS_CORETYPE=Nehalem`` keeps OpenBLAS on SSE kernels. These are passed on the kernel
  command line, which hands unknown ``KEY=VALUE`` words to init as its environment.

``ECU_UML_NO_SECCOMP=1`` turns both off (for hosts where UML works natively).
"""
from __future__ import annotations

import argparse
import ctypes
import os
import shutil
import signal
import struct
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
UML_PACKAGES = ("user-mode-linux", "kmod", "can-utils")
KERNEL_CANDIDATES = ("/usr/bin/linux.uml", "/usr/bin/linux")
MODULES_ROOT = Path("/usr/lib/uml/modules")
INSTALL_STAMP = Path("/var/cache/ecu-daemon-uml/apt-installed")

GLIBC_TUNABLES = ("glibc.cpu.hwcaps=-AVX512F,-AVX512VL,-AVX512BW,-AVX512DQ,-AVX512CD,-AVX2,-AVX,"
                  "-AVX_Fast_Unaligned_Load")


class UmlUnavailable(Exception):
    """UML cannot run here; the message says why (tests turn it into a skip reason)."""


class UmlInstallFailed(RuntimeError):
    """Installing the packages was asked for and failed (a failure, not a missing capability)."""


# --------------------------------------------------------------------------- kernel and packages

def find_kernel() -> Path | None:
    for c in KERNEL_CANDIDATES:
        if os.access(c, os.X_OK):
            return Path(c)
    return None


def modules_dir() -> Path | None:
    """``/usr/lib/uml/modules/<version>`` of the installed UML kernel."""
    if not MODULES_ROOT.is_dir():
        return None
    versions = sorted(p for p in MODULES_ROOT.iterdir() if p.is_dir())
    return versions[-1] if versions else None


def install_allowed() -> bool:
    """Install packages only as root, and only in CI or when asked (never behind a developer's back)."""
    return os.geteuid() == 0 and (os.environ.get("CI") == "true" or os.environ.get("ECU_UML_INSTALL") == "1")


def missing_tools(extra: tuple[str, ...] = ()) -> list[str]:
    need = {"insmod": "kmod", "candump": "can-utils", "canplayer": "can-utils", "ip": "iproute2"}
    need.update({t: t for t in extra})
    miss = [pkg for tool, pkg in need.items() if shutil.which(tool) is None
            and not os.access(f"/sbin/{tool}", os.X_OK) and not os.access(f"/usr/sbin/{tool}", os.X_OK)]
    if find_kernel() is None or modules_dir() is None:
        miss.append("user-mode-linux")
    return sorted(set(miss))


def ensure_installed(extra_packages: tuple[str, ...] = (), log=None) -> None:
    """apt-get the UML kernel + tools once (root, CI only).

    Raises :class:`UmlUnavailable` when they are missing and may not be installed here, and
    :class:`UmlInstallFailed` when installing them was allowed and did not work.
    """
    extra_tools = tuple(p for p in extra_packages if p not in UML_PACKAGES)
    missing = missing_tools(extra_tools)
    if not missing:
        return
    if not install_allowed():
        raise UmlUnavailable(
            f"missing {', '.join(missing)}; install with `apt-get install -y {' '.join(UML_PACKAGES + extra_packages)}`"
            " (the harness installs them itself only as root with CI=true or ECU_UML_INSTALL=1)")
    if shutil.which("apt-get") is None:
        raise UmlUnavailable("missing " + ", ".join(missing) + " and no apt-get to install them")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    out = subprocess.DEVNULL if log is None else log
    t = time.monotonic()
    for cmd in (["apt-get", "update", "-q"],
                ["apt-get", "install", "-y", "-q", "--no-install-recommends", *UML_PACKAGES, *extra_packages]):
        try:
            r = subprocess.run(cmd, env=env, stdout=out, stderr=subprocess.STDOUT, timeout=600)
        except subprocess.TimeoutExpired:
            raise UmlInstallFailed(f"`{' '.join(cmd)}` took more than 600 s") from None
        if r.returncode != 0:
            raise UmlInstallFailed(f"`{' '.join(cmd)}` failed with status {r.returncode}")
    INSTALL_STAMP.parent.mkdir(parents=True, exist_ok=True)
    INSTALL_STAMP.write_text(f"{' '.join(UML_PACKAGES + extra_packages)} in {time.monotonic() - t:.1f} s\n")
    still = missing_tools(extra_tools)
    if still:
        raise UmlInstallFailed(f"still missing after apt-get install: {', '.join(still)}")


# --------------------------------------------------------------------------- seccomp workaround

def _bpf(code: int, jt: int, jf: int, k: int) -> bytes:
    return struct.pack("HBBI", code, jt, jf, k)


def xstate_filter_program() -> bytes:
    """BPF: ptrace(PTRACE_GETREGSET|PTRACE_SETREGSET, pid, NT_X86_XSTATE, ...) -> EIO; all else allowed."""
    LD, JEQ, RET = 0x20, 0x15, 0x06  # BPF_LD|BPF_W|BPF_ABS, BPF_JMP|BPF_JEQ|BPF_K, BPF_RET|BPF_K
    ALLOW, EIO = 0x7FFF0000, 0x00050000 | 5
    return b"".join([
        _bpf(LD, 0, 0, 4), _bpf(JEQ, 0, 7, 0xC000003E),  # arch == AUDIT_ARCH_X86_64 else allow
        _bpf(LD, 0, 0, 0), _bpf(JEQ, 0, 5, 101),  # nr == __NR_ptrace else allow
        _bpf(LD, 0, 0, 16), _bpf(JEQ, 1, 0, 0x4204), _bpf(JEQ, 0, 2, 0x4205),  # request GET/SETREGSET
        _bpf(LD, 0, 0, 32), _bpf(JEQ, 1, 0, 0x202),  # addr == NT_X86_XSTATE
        _bpf(RET, 0, 0, ALLOW), _bpf(RET, 0, 0, EIO),
    ])


def _install_xstate_filter() -> None:  # runs in the child between fork and exec
    libc = ctypes.CDLL(None, use_errno=True)

    class SockFprog(ctypes.Structure):
        _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]

    prog = xstate_filter_program()
    buf = ctypes.create_string_buffer(prog, len(prog))
    fprog = SockFprog(len(prog) // 8, ctypes.cast(buf, ctypes.c_void_p))
    if os.geteuid() != 0:
        libc.prctl(38, 1, 0, 0, 0)  # PR_SET_NO_NEW_PRIVS, required without CAP_SYS_ADMIN
    if libc.prctl(22, 2, ctypes.byref(fprog), 0, 0) != 0:  # PR_SET_SECCOMP, SECCOMP_MODE_FILTER
        os.write(2, b"uml boot: cannot install the seccomp filter\n")
        os._exit(126)
    _new_session()


#: nice(2) increment for the guest (root only): a UML guest is one ptrace-driven process tree that
#: must keep a 6 ms schedule; on a host loaded several times over by other work it otherwise
#: falls seconds behind real time (inputs buffered, estimates late), which is no property of the
#: software under test. ``ECU_UML_NICE=0`` leaves the guest at normal priority.
GUEST_NICE = -10


def _new_session() -> None:  # runs in the child between fork and exec
    os.setsid()
    if os.geteuid() == 0:
        os.nice(int(os.environ.get("ECU_UML_NICE", GUEST_NICE)))


def _numpy_simd_targets() -> list[str]:
    """numpy's dispatch targets this CPU supports (all above the SSE baseline) -> to disable."""
    import numpy

    return list(numpy.show_config(mode="dicts").get("SIMD Extensions", {}).get("found", []))


def guest_environment() -> dict[str, str]:
    """Environment every guest process needs (see the module docstring); no spaces allowed."""
    if os.environ.get("ECU_UML_NO_SECCOMP") == "1":
        return {}
    env = {"GLIBC_TUNABLES": GLIBC_TUNABLES, "OPENBLAS_CORETYPE": "Nehalem"}
    targets = _numpy_simd_targets()
    if targets:
        env["NPY_DISABLE_CPU_FEATURES"] = ",".join(targets)
    return env


# --------------------------------------------------------------------------- booting

@dataclass
class BootResult:
    returncode: int | None
    seconds: float
    timed_out: bool
    console: Path

    def console_tail(self, n: int = 40) -> str:
        try:
            lines = self.console.read_text(errors="replace").splitlines()
        except OSError:
            return "(no console log)"
        return "\n".join(lines[-n:])


def boot(init: str, *, console: Path, rootfs: str = "/", mem: str = "768M", timeout: float = 300.0,
         env: dict[str, str] | None = None, extra_args: tuple[str, ...] = ()) -> BootResult:
    """Boot UML with a hostfs root and ``init`` as PID 1; kill it if it runs past ``timeout``.

    ``env`` (plus :func:`guest_environment`) reaches init as its environment via the kernel command
    line, so values must not contain spaces. The console (kernel log + init's stdout) goes to
    ``console``. Every host process of the guest is in one new session and is killed on time-out.
    """
    kernel = find_kernel()
    if kernel is None:
        raise UmlUnavailable("no UML kernel (/usr/bin/linux.uml): apt-get install user-mode-linux")
    words = {**guest_environment(), **(env or {})}
    for k, v in words.items():
        if any(c.isspace() for c in v):
            raise ValueError(f"guest environment {k}={v!r} must not contain whitespace")
    umid = f"ecu{os.getpid()}-{time.monotonic_ns() % 10**9}"
    uml_dir = console.parent / ".uml"
    uml_dir.mkdir(parents=True, exist_ok=True)
    cmd = [str(kernel), f"mem={mem}", "rootfstype=hostfs", f"rootflags={rootfs}", "rw", f"init={init}",
           f"umid={umid}", f"uml_dir={uml_dir}", "con=null", "con0=fd:0,fd:1", "quiet", *extra_args,
           *(f"{k}={v}" for k, v in words.items())]
    use_filter = os.environ.get("ECU_UML_NO_SECCOMP") != "1"
    t0 = time.monotonic()
    with open(console, "wb") as out:
        out.write(("# " + " ".join(cmd) + "\n").encode())
        out.flush()
        proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                preexec_fn=_install_xstate_filter if use_filter else _new_session,
                                env={k: v for k, v in os.environ.items() if k != "TMPDIR"})
        timed_out = False
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            timed_out = True
        finally:
            _kill_group(proc)
    shutil.rmtree(uml_dir / umid, ignore_errors=True)
    return BootResult(None if timed_out else proc.returncode, time.monotonic() - t0, timed_out, console)


def _kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL the guest's whole session (UML's helper and per-process host threads included)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        pass


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--init", default=str(HERE / "guest_init.sh"), help="PID 1 of the guest (a host path)")
    p.add_argument("--rootfs", default="/", help="host directory exported as the guest's / (hostfs)")
    p.add_argument("--console", default="uml-console.log")
    p.add_argument("--timeout", type=float, default=300.0)
    p.add_argument("--mem", default="768M")
    p.add_argument("--install", action="store_true", help="apt-get the UML packages if missing (root)")
    p.add_argument("env", nargs="*", help="KEY=VALUE words for init's environment")
    a = p.parse_args(argv)
    try:
        if a.install:
            os.environ["ECU_UML_INSTALL"] = "1"
        ensure_installed()
        env = dict(w.split("=", 1) for w in a.env)
        r = boot(a.init, console=Path(a.console).resolve(), rootfs=a.rootfs, mem=a.mem, timeout=a.timeout, env=env)
    except (UmlUnavailable, UmlInstallFailed) as e:
        print(f"uml: {e}", file=sys.stderr)
        return 3
    print(f"uml: {'TIMED OUT after' if r.timed_out else 'exited ' + str(r.returncode) + ' after'} "
          f"{r.seconds:.1f} s; console in {r.console}", file=sys.stderr)
    return 1 if r.timed_out else 0


if __name__ == "__main__":
    raise SystemExit(main())
