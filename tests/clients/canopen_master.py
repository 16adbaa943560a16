#!/usr/bin/env python3
"""python-canopen as the CANopen master of whirl-sim's three CiA 402 drives.

Usage: canopen_master.py PORT EDS

PORT is the pseudo-terminal `whirl-sim --can-slcan` serves; python-can's slcan interface
talks to it as to a CANable adapter (1 Mbit/s). EDS is the drives' electronic data sheet
(tests/data/cia402-drive.eds), the object dictionary python-canopen reads them with.
Written from CiA 301, CiA 402 and python-canopen's documented API; nothing of whirl's.

The master does what a commissioning tool does with a new drive, on nodes 1, 2 and 3:
NMT reset communication and the boot-ups; SDO reads of the device type, the identity and
the mode; the mode written (cyclic synchronous position, 8) and read back; the
interpolation period (60C2h) and the heartbeat (1017h) written; RPDO1 and TPDO1 mapped by
python-canopen's pdo module (disable, clear, map, re-enable, as CiA 301 orders it); NMT
start; the CiA 402 state machine walked to Operation enabled by BaseNode402 on the PDOs,
with SYNC every period; a short straight path of set-points followed; the heartbeats
consumed; a following-error fault (its EMCY) and its reset. Each check prints a line;
the first that fails raises, and the exit status is 1.
"""

import sys
import threading
import time

import canopen

NODES = (1, 2, 3)
# The SYNC period, written to each drive's interpolation time period (60C2h): 10 ms, so
# that Python's SYNC thread keeps to it.
PERIOD_MS = 10
HEARTBEAT_MS = 50
# Each set-point moves every axis this many counts further: under the drives' largest step
# a cycle, so that they follow it exactly.
STEP = 300
STEPS = 100
# How long a python-canopen wait may take: the drives answer within a cycle, but this
# process, the simulator and other builds share two cores; a state change that has not
# come in seconds will not come.
PATIENCE_S = 5.0
MODE_CSP = 8
EMCY_FOLLOWING_ERROR = 0x8611


def check(ok, what):
    if not ok:
        raise AssertionError(what)
    print("ok:", what, flush=True)


class Heard:
    """Boot-ups and heartbeats of every node (CiA 301: one byte on 0x700 + node, 0 for
    a boot-up, else the NMT state), with their times."""

    def __init__(self, network):
        self.lock = threading.Lock()
        self.messages = {node: [] for node in NODES}
        for node in NODES:
            network.subscribe(0x700 + node, self.on_message)

    def on_message(self, can_id, data, timestamp):
        with self.lock:
            self.messages[can_id - 0x700].append((time.monotonic(), data[0]))

    def of(self, node, since=0.0):
        with self.lock:
            return [state for (t, state) in self.messages[node] if t >= since]


class Positions:
    """Every position actual value (6064h) a drive's TPDO1 carried, in order."""

    def __init__(self, drives):
        self.lock = threading.Lock()
        self.seen = {node: [] for node in NODES}
        for node, drive in drives.items():
            drive.tpdo[1].add_callback(self.callback(node))

    def callback(self, node):
        def on_tpdo(pdo):
            with self.lock:
                self.seen[node].append(pdo[0x6064].raw)

        return on_tpdo

    def since(self, node, k):
        with self.lock:
            return list(self.seen[node][k:])

    def count(self, node):
        with self.lock:
            return len(self.seen[node])


def wait_until(condition, what):
    deadline = time.monotonic() + PATIENCE_S
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError("timed out: " + what)
        time.sleep(0.005)


def configure(drive, node):
    # Device type (CiA 301 1000h): the profile's number, 402, in the low word.
    device_type = drive.sdo[0x1000].raw
    check(device_type & 0xFFFF == 402, f"node {node}: device type {device_type:#010x}, CiA 402")
    identity = drive.sdo[0x1018]
    highest = identity[0].raw
    check(highest >= 1, f"node {node}: identity 1018h has {highest} sub-indices")
    vendor, product, revision, serial = (identity[k].raw for k in range(1, 5))
    print(
        f"node {node}: vendor {vendor:#x}, product {product}, revision {revision:#x}, "
        f"serial {serial}",
        flush=True,
    )
    drive.sdo[0x6060].raw = MODE_CSP
    check(drive.sdo[0x6061].raw == MODE_CSP, f"node {node}: 6061h shows mode 8 (CSP)")
    period = drive.sdo[0x60C2]
    period[1].raw = PERIOD_MS
    period[2].raw = -3
    check(
        (period[1].raw, period[2].raw) == (PERIOD_MS, -3),
        f"node {node}: interpolation period {PERIOD_MS} x 10^-3 s",
    )
    drive.sdo[0x1017].raw = HEARTBEAT_MS
    # The PDOs as python-canopen's pdo module maps them: RPDO1 controlword and target
    # position, TPDO1 statusword and position actual value, both on every SYNC
    # (transmission type 1).
    drive.rpdo.read()
    drive.tpdo.read()
    rpdo, tpdo = drive.rpdo[1], drive.tpdo[1]
    rpdo.clear()
    rpdo.add_variable(0x6040)
    rpdo.add_variable(0x607A)
    rpdo.trans_type = 1
    rpdo.enabled = True
    tpdo.clear()
    tpdo.add_variable(0x6041)
    tpdo.add_variable(0x6064)
    tpdo.trans_type = 1
    tpdo.enabled = True
    rpdo.save()
    tpdo.save()
    mapped = [drive.sdo[0x1A00][k].raw for k in range(3)]
    check(
        mapped == [2, 0x60410010, 0x60640020],
        f"node {node}: TPDO1 mapped by SDO as written: {[hex(m) for m in mapped]}",
    )


def run(network, eds):
    drives = {}
    for node in NODES:
        drive = canopen.BaseNode402(node, eds)
        for name in (
            "TIMEOUT_RESET_FAULT",
            "TIMEOUT_SWITCH_STATE_FINAL",
            "TIMEOUT_SWITCH_STATE_SINGLE",
            "TIMEOUT_CHECK_TPDO",
        ):
            setattr(drive, name, PATIENCE_S)
        drive.sdo.RESPONSE_TIMEOUT = PATIENCE_S
        network.add_node(drive)
        drives[node] = drive
    heard = Heard(network)

    network.nmt.state = "RESET COMMUNICATION"
    wait_until(lambda: all(0 in heard.of(n) for n in NODES), "boot-ups after reset")
    check(True, "every node sent its boot-up after NMT reset communication")

    for node, drive in drives.items():
        configure(drive, node)

    network.nmt.state = "OPERATIONAL"
    network.sync.start(PERIOD_MS / 1000)
    try:
        follow_a_path(drives, heard)
        fault_and_reset(drives[1])
        for node, drive in drives.items():
            drive.state = "SWITCH ON DISABLED"
            check(drive.state == "SWITCH ON DISABLED", f"node {node}: disabled")
    finally:
        for drive in drives.values():
            drive.rpdo[1].stop()
        network.sync.stop()
    network.nmt.state = "PRE-OPERATIONAL"


def follow_a_path(drives, heard):
    for node, drive in drives.items():
        drive.setup_402_state_machine(read_pdos=False)
    positions = Positions(drives)
    wait_until(lambda: all(positions.count(n) > 0 for n in NODES), "the first TPDOs")
    start = {n: positions.since(n, 0)[-1] for n in NODES}
    for node, drive in drives.items():
        # CSP follows 607Ah from Operation enabled on: it must be where the drive stands.
        # RPDO1 is synchronous: python-canopen sends it every period, as a SYNC thread
        # does SYNC, and the drive applies the last one at each SYNC.
        drive.rpdo[1][0x607A].raw = start[node]
        drive.rpdo[1].start(PERIOD_MS / 1000)
    for node, drive in drives.items():
        drive.state = "OPERATION ENABLED"
        check(drive.state == "OPERATION ENABLED", f"node {node}: Operation enabled")
    since = time.monotonic()
    first = {n: positions.count(n) for n in NODES}
    for k in range(1, STEPS + 1):
        seen = positions.count(1)
        for node, drive in drives.items():
            drive.rpdo[1][0x607A].raw = start[node] + k * STEP
        wait_until(lambda: positions.count(1) > seen, "a TPDO after a set-point")
    end = {n: start[n] + STEPS * STEP for n in NODES}
    wait_until(
        lambda: all(positions.since(n, 0)[-1] == end[n] for n in NODES),
        "the drives at the path's end",
    )
    for node in NODES:
        path = positions.since(node, first[node])
        # Each position lies between the start and the end, and never goes back: the
        # drive followed the straight path the set-points make.
        check(
            all(start[node] <= p <= end[node] for p in path)
            and all(a <= b for a, b in zip(path, path[1:])),
            f"node {node}: followed {STEPS} set-points from {start[node]} to {end[node]}",
        )
        word = drives[node].statusword
        # CiA 402 statusword, CSP: bit 12 target followed, bit 13 following error.
        check(word & 0x1000 and not word & 0x2000, f"node {node}: statusword {word:#06x}")
    # The heartbeat consumed: at least one every 50 ms of the drives' time, which the
    # SYNCs clock (one period each) and the wall clock can only add to; Operational (5).
    elapsed_syncs = min(positions.count(n) - first[n] for n in NODES)
    for node in NODES:
        beats = heard.of(node, since)
        expected = elapsed_syncs * PERIOD_MS // HEARTBEAT_MS - 1
        check(
            len(beats) >= expected and set(beats) == {5},
            f"node {node}: {len(beats)} heartbeats (at least {expected}), all Operational",
        )


def fault_and_reset(drive):
    # A following error: the window (6065h) narrowed to 100 counts, a target 50 000 counts
    # off. The drive faults (CiA 402 Fault) and says why by EMCY 8611h.
    window = drive.sdo[0x6065].raw
    drive.sdo[0x6065].raw = 100
    here = drive.tpdo[1][0x6064].raw
    drive.rpdo[1][0x607A].raw = here + 50_000
    # (Looked for in the consumer's log: `emcy.wait` only sees one that comes after it is
    # called, and this process may be descheduled past the cycle the fault comes in.)
    wait_until(
        lambda: any(e.code == EMCY_FOLLOWING_ERROR for e in drive.emcy.log),
        "the following error's EMCY",
    )
    check(True, f"node {drive.id}: EMCY {EMCY_FOLLOWING_ERROR:#06x}, following error")
    wait_until(lambda: drive.state == "FAULT", "the Fault state")
    check(True, f"node {drive.id}: Fault")
    drive.sdo[0x6065].raw = window
    # Back to Operation enabled through the fault reset, the target where it stands.
    drive.rpdo[1][0x607A].raw = drive.tpdo[1][0x6064].raw
    drive.reset_from_fault()
    check(drive.state == "OPERATION ENABLED", f"node {drive.id}: reset, Operation enabled")


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    port, eds = sys.argv[1], sys.argv[2]
    network = canopen.Network()
    network.connect(interface="slcan", channel=port, bitrate=1_000_000, sleep_after_open=0)
    try:
        run(network, eds)
    finally:
        network.disconnect()
    print("done", flush=True)


if __name__ == "__main__":
    main()
