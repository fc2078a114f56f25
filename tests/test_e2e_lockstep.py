"""The same seed gives the same run whatever else the machine does (issue 38), end to end.

Each scenario runs ``swarm-up`` twice with the same flags and a process per navigator and per
commander: once as it is, once with the cores kept busy beside it (busy loops, each in a
session of its own, and a process writing to the disk) while its navigator, commander and
coordinator processes are paused (SIGSTOP) for one to two seconds at a time, one after the
other, for the whole run (:mod:`tests.support.stress`). Both runs must say ``reproducible: yes``
and give the same simulated figures: tasks and their times, every robot's goals and distance,
collisions, the minimum separation, the workstations, the faults' log. No wall-clock timeout
decides anything simulated (docs/ARCHITECTURE.md, "Synchronous control loop"), so a stall costs
wall time only.
"""

from __future__ import annotations

import json

import pytest

from tests.support.stress import BusyLoops, Pauser
from tests.test_e2e_swarm_up import (
    EXIT_SLACK_S,
    READY_TIMEOUT_S,
    SwarmUp,
    _diff,
    _run_to_end,
    _simulated,
)

pytestmark = pytest.mark.e2e

PAUSED = ("swarm-nav", "swarm-commander", "swarm-coordinator", "swarm_up.group")
COMMON = ["--commanders", "--rtf", "0", "--processes", "per-robot"]
SCENARIOS = {
    "decentralized": ["--swarm-size", "4", "--duration", "75", "--seed", "9"],
    "kill-nav": ["--swarm-size", "4", "--duration", "75", "--seed", "9",
                 "--faults", "kill-nav:2@30+3"],
    "centralized, coordinator restarted": [
        "--swarm-size", "6", "--duration", "100", "--seed", "2",
        "--coordination", "centralized", "--faults", "kill-coordinator@40+10"],
}


def _stressed_run(args: list[str], tmp_path, duration_s: float):
    """The run with busy cores and paused processes: (metrics, diagnostics, pauses)."""
    with BusyLoops(4, disk_file=str(tmp_path / "disk.bin")), \
            SwarmUp(args, tmp_path, "stressed") as run:
        # a pause every 0.3-1.0 s: at 0.5-1.5 s a 4-robot run once ended after 4 pauses
        pauser = Pauser(run.proc.pid, PAUSED, seed=38, every_s=(0.3, 1.0))
        pauser.start()
        try:
            code = run.wait(READY_TIMEOUT_S + 4 * duration_s + EXIT_SLACK_S)
        finally:
            pauser.stop()
        diag = run.diagnostics()
        assert code == 0, f"swarm-up exited with {code}\n{diag}"
        return run.metrics(), diag, pauser.pauses


@pytest.mark.parametrize("scenario", list(SCENARIOS))
def test_a_busy_machine_and_paused_processes_change_nothing_simulated(scenario, tmp_path):
    args = COMMON + SCENARIOS[scenario]
    duration = float(args[args.index("--duration") + 1])
    _, quiet, diag1 = _run_to_end(args, tmp_path, "quiet", duration)
    stressed, diag2, pauses = _stressed_run(args, tmp_path, duration)
    kinds = {what for what, _ in pauses}
    assert len(pauses) >= 5 and {"swarm-nav", "swarm-commander"} <= kinds, (
        f"the processes were not paused enough to test anything: {pauses}")
    for m, diag in ((quiet, diag1), (stressed, diag2)):
        why = {k: m.get(k) for k in ("late_ticks", "goal_wait_timeouts", "late_goals",
                                     "restarts", "coordinator_starts", "fault_log")}
        assert m["reproducible"] is True, f"not reproducible: {json.dumps(why)}\n{diag}"
        assert m["tasks_completed"] > 0 and m["late_ticks"] == 0, diag
    a, b = _simulated(quiet), _simulated(stressed)
    for m in (a, b):  # copies of a message sent again for want of an answer: wall-clock timing
        m["comm"] = {k: v for k, v in m["comm"].items() if k != "resent"}
    diffs = _diff(a, b)
    assert not diffs, (f"{len(pauses)} pauses ({sorted(kinds)}) changed the simulated run:\n  "
                       + "\n  ".join(diffs[:30])
                       + f"\nquiet run:\n{diag1}\nstressed run:\n{diag2}")
