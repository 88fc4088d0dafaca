"""kill -9 in the middle of a burst of PARAM_SETs: the parameter file survives (issue 11.3).

The real companion runs with ``--params FILE`` (a hand-written file with comments); a ground
station on UDP sends a burst of PARAM_SETs, each of which makes the companion save the file
(the previous one kept as FILE.bak), and the process is killed with SIGKILL at a different
moment of the burst in each trial. After each kill the file and its .bak must load, hold the
hand-written comments, and hold for every parameter either its old value or one that was sent;
a temporary file may be left only if the kill landed inside a write, and the next start removes
it. Trials run back to back on the same file, so each starts where the previous kill left it.
"""

from __future__ import annotations

import random
import signal
import socket
import time
from pathlib import Path

from sitl import CompanionProcess

from mecanum_mav.io.paramfile import load
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.groundstation import udp_ground_station

TRIALS = 8
SENT = {  # parameter -> the values the burst cycles through
    "OUT_RATE": (20.0, 25.0, 30.0),
    "FS_INPUT_TMO": (0.5, 0.6, 0.7),
    "WP_SPEED": (0.5, 0.4, 0.3),
    "GUID_SPD_MAX": (0.7, 0.6),
}
HAND_WRITTEN = """\
# my rover: bench setup
OUT_RATE 20
# inputs
FS_INPUT_TMO 0.5
WP_SPEED 0.5
"""


def burst():
    """PARAM_SETs for ever: the parameters in turn, each cycling through its values."""
    items = list(SENT.items())
    i = 0
    while True:
        name, values = items[i % len(items)]
        yield name, values[(i // len(items)) % len(values)]
        i += 1


def stray_temporaries(directory: Path) -> list[Path]:
    return sorted(p for p in directory.iterdir() if p.name.endswith(".tmp"))


def check_survivor(path: Path) -> None:
    """The file loads, keeps the comments, and holds an old or a sent value of each."""
    text = path.read_text()
    assert text.startswith("# my rover: bench setup\n") and "# inputs\n" in text, text
    params = load(path)
    for name, values in SENT.items():
        assert any(abs(float(params[name]) - v) < 1e-6 for v in values), (path, name,
                                                                          params[name])


def test_kill_9_during_a_burst_of_param_sets_leaves_complete_files_and_no_temporaries(
        tmp_path: Path) -> None:
    path = tmp_path / "rover.parm"
    path.write_text(HAND_WRITTEN)
    rng = random.Random(11)
    fc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    fc.bind(("127.0.0.1", 0))
    fc_url = f"udpout:127.0.0.1:{fc.getsockname()[1]}"
    cut_inside_a_write = 0
    try:
        for trial in range(TRIALS):
            gcs, port = udp_ground_station()
            try:
                with CompanionProcess(port.url, fc_url, tmp_path / f"run{trial}", "--params",
                                      str(path)) as companion:
                    assert gcs.wait("HEARTBEAT", timeout_s=10.0), companion.log()
                    # the start removed what the previous kill left
                    assert stray_temporaries(tmp_path) == [], companion.log()
                    kill_after = rng.uniform(0.0, 0.25)
                    start = None
                    for n, (name, value) in enumerate(burst()):
                        gcs.mav.param_set_send(1, 1, name.encode(), value,
                                               mavlink.MAV_PARAM_TYPE_REAL32)
                        if start is None:  # the first answer: the first save has happened
                            assert gcs.wait("PARAM_VALUE", timeout_s=15.0), companion.log()
                            start = time.monotonic()
                        elif n % 8 == 0:
                            gcs.pump(0.001)  # a steady stream, not one burst in the queue
                        if time.monotonic() - start >= kill_after:
                            break
                    companion.proc.send_signal(signal.SIGKILL)
                    assert companion.wait(5.0) == -signal.SIGKILL
            finally:
                port.close()
            check_survivor(path)
            check_survivor(path.with_name(path.name + ".bak"))
            cut_inside_a_write += bool(stray_temporaries(tmp_path))
        gcs, port = udp_ground_station()
        try:  # one more start: whatever the last kill left is removed
            with CompanionProcess(port.url, fc_url, tmp_path / "last", "--params",
                                  str(path)) as companion:
                assert gcs.wait("HEARTBEAT", timeout_s=10.0), companion.log()
                assert stray_temporaries(tmp_path) == []
        finally:
            port.close()
    finally:
        fc.close()
    print(f"{TRIALS} kills, {cut_inside_a_write} inside a write")
