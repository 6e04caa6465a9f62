"""A one-node SLURM cluster on this machine, for tests: munge, slurmctld and slurmd (Debian's
``slurm-wlm`` and ``munge``, installed by ``scripts/setup.sh``) started in the foreground on free
loopback ports with their own key, config and state under a temporary folder, and stopped again.

    with one_node_cluster(tmp_path) as env:   # env: os.environ + SLURM_CONF
        subprocess.run(["sbatch", ...], env=env)

:func:`missing` says why a cluster cannot be started here (no binaries, not root), for a skip.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import time
from pathlib import Path

DAEMONS = ("munged", "mungekey", "slurmctld", "slurmd", "sbatch", "sinfo", "scancel")
NODE, PARTITION = "localnode", "debug"


def missing() -> str | None:
    """Why no cluster can be started here, or None."""
    gone = [d for d in DAEMONS if not _which(d)]
    if gone:
        return f"no {', '.join(gone)} (Debian: apt-get install slurm-wlm munge; scripts/setup.sh does it as root)"
    if os.geteuid() != 0:
        return "slurmd must run as root to start jobs as their user, and this is not root"
    return None


def _which(name: str) -> str | None:
    return shutil.which(name) or shutil.which(name, path="/usr/sbin:/sbin")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _config(folder: Path, socket_path: Path) -> str:
    ctld, slurmd = _free_port(), _free_port()
    cpus = os.cpu_count() or 1
    return "\n".join(
        [
            "ClusterName=pipelinetest",
            "SlurmctldHost=localhost(127.0.0.1)",
            "SlurmUser=root",
            "SlurmdUser=root",
            "AuthType=auth/munge",
            f"AuthInfo=socket={socket_path}",
            "CredType=cred/munge",
            f"StateSaveLocation={folder / 'state'}",
            f"SlurmdSpoolDir={folder / 'spool'}",
            f"SlurmctldPidFile={folder / 'slurmctld.pid'}",
            f"SlurmdPidFile={folder / 'slurmd.pid'}",
            f"SlurmctldLogFile={folder / 'slurmctld.log'}",
            f"SlurmdLogFile={folder / 'slurmd.log'}",
            f"SlurmctldPort={ctld}",
            f"SlurmdPort={slurmd}",
            "ProctrackType=proctrack/linuxproc",
            "TaskPlugin=task/none",
            "SchedulerType=sched/builtin",
            "SelectType=select/cons_tres",
            "SelectTypeParameters=CR_Core",
            "ReturnToService=2",
            "MpiDefault=none",
            "JobCompType=jobcomp/none",
            "JobAcctGatherType=jobacct_gather/none",
            "AccountingStorageType=accounting_storage/none",
            f"NodeName={NODE} NodeAddr=127.0.0.1 CPUs={cpus} RealMemory=2000 State=UNKNOWN",
            f"PartitionName={PARTITION} Nodes={NODE} Default=YES MaxTime=INFINITE State=UP",
            "",
        ]
    )


@contextlib.contextmanager
def one_node_cluster(folder: Path, timeout: float = 60.0):
    """Start the cluster in ``folder``; yield the environment that points SLURM's commands at it."""
    folder = Path(folder)
    for sub in ("munge", "state", "spool"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    key, sock = folder / "munge" / "munge.key", folder / "munge" / "munge.socket"
    subprocess.run(
        [_which("mungekey"), "-c", "-f", "-k", str(key)], check=True, capture_output=True
    )
    key.chmod(0o600)
    conf = folder / "slurm.conf"
    conf.write_text(_config(folder, sock))
    env = {**os.environ, "SLURM_CONF": str(conf)}
    logs = open(folder / "daemons.log", "ab")  # noqa: SIM115 - closed below
    procs = []

    def start(*cmd: str) -> None:
        procs.append(
            subprocess.Popen(
                [_which(cmd[0]), *cmd[1:]],
                env=env,
                stdout=logs,
                stderr=logs,
                start_new_session=True,
            )
        )

    try:
        start(
            "munged",
            "--foreground",
            "--force",
            f"--key-file={key}",
            f"--socket={sock}",
            f"--pid-file={folder / 'munge' / 'munged.pid'}",
            f"--log-file={folder / 'munge' / 'munged.log'}",
            f"--seed-file={folder / 'munge' / 'munged.seed'}",
        )
        _wait(lambda: sock.exists(), timeout, "munged did not create its socket", folder)
        start("slurmctld", "-D", "-i", "-f", str(conf))
        start("slurmd", "-D", "-N", NODE, "-f", str(conf))
        _wait(
            lambda: (
                subprocess.run(
                    [_which("sinfo"), "-h", "-N", "-o", "%T"],
                    env=env,
                    capture_output=True,
                    text=True,
                ).stdout.strip()
                == "idle"
            ),
            timeout,
            "the node did not become idle",
            folder,
        )
        yield env
    finally:
        with contextlib.suppress(
            OSError, subprocess.SubprocessError
        ):  # jobs first, so their steps end
            subprocess.run(
                [_which("scancel"), "--full", "--user", "root"],
                env=env,
                timeout=10,
                capture_output=True,
            )
        for p in reversed(procs):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGTERM)
        for p in reversed(procs):
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        logs.close()
        _kill_leftovers(f"SLURM_CONF={conf}".encode())


def _kill_leftovers(mark: bytes) -> None:
    """Job steps (slurmstepd and what it started) outlive slurmd: end every process whose environment
    points at this cluster's config."""
    for pid in (
        int(p.name)
        for p in Path("/proc").iterdir()
        if p.name.isdigit() and int(p.name) != os.getpid()
    ):
        with contextlib.suppress(OSError):
            if mark in Path(f"/proc/{pid}/environ").read_bytes().split(b"\0"):
                os.kill(pid, signal.SIGKILL)


def _wait(ok, timeout: float, what: str, folder: Path) -> None:
    end = time.monotonic() + timeout
    while not ok():
        if time.monotonic() > end:
            tail = "".join(
                p.read_text(errors="replace")[-1500:] for p in sorted(folder.glob("*.log"))
            )
            raise RuntimeError(f"{what} within {timeout:.0f} s; logs:\n{tail}")
        time.sleep(0.2)
