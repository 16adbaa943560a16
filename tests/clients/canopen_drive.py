#!/usr/bin/env python3
"""Three CiA 402 drives served by python-canopen, behind an slcan adapter on a pseudo-terminal.

Usage: canopen_drive.py EDS LOG

A CANopen master (whirl's) opens the terminal whose path this prints as its first line
of output, as it would a CANable adapter's serial port. Behind it, on a python-can virtual
bus, nodes 1, 2 and 3 are python-canopen LocalNodes whose object dictionary is read from
EDS (tests/data/cia402-drive.eds): python-canopen serves their NMT (boot-up, heartbeat on
1017h) and their SDO server. What python-canopen leaves to a drive's firmware is written
here, from CiA 301 and CiA 402 alone (nothing of whirl's): the PDOs as the mapping objects
say at each SYNC, the power state machine of 6040h/6041h and a cyclic synchronous position
loop that follows 607Ah.

LOG gets a JSON line for everything the master did to the drives: each SDO write
(node, index, sub-index, value), each power state entered, and each SYNC's targets and
positions. The process ends once no byte has come for 5 s.
"""

import json
import os
import sys
import threading
import time
import tty

import can
import canopen

NODES = (1, 2, 3)
CHANNEL = "whirl-canopen-drive"
IDLE_EXIT_S = 5.0

# CiA 402 statusword values of the power states (bits 0-3, 5, 6), with voltage enabled
# (bit 4) and remote (bit 9).
STATUS = {
    "SWITCH ON DISABLED": 0x0040,
    "READY TO SWITCH ON": 0x0021,
    "SWITCHED ON": 0x0023,
    "OPERATION ENABLED": 0x0027,
    "QUICK STOP ACTIVE": 0x0007,
    "FAULT": 0x0008,
}
VOLTAGE_ENABLED, REMOTE, TARGET_FOLLOWED = 0x0010, 0x0200, 0x1000
MODE_CSP = 8


class Log:
    def __init__(self, path):
        self.file = open(path, "a", buffering=1)
        self.lock = threading.Lock()

    def write(self, **event):
        with self.lock:
            self.file.write(json.dumps(event) + "\n")


def next_state(state, controlword, previous):
    """The CiA 402 power state after `controlword` (its transitions 2-12, 15, 16; 3 and 4
    at once for switch on + enable operation from Ready to switch on)."""
    if state == "FAULT":
        rising = controlword & 0x80 and not previous & 0x80
        return "SWITCH ON DISABLED" if rising else state
    if controlword & 0x80:
        return state
    if not controlword & 0x02:  # disable voltage: 7, 9, 10, 12
        return "SWITCH ON DISABLED"
    if not controlword & 0x04:  # quick stop: 7, 10, 11
        return "QUICK STOP ACTIVE" if state == "OPERATION ENABLED" else "SWITCH ON DISABLED"
    command = controlword & 0x0F
    if command == 0x06:  # shutdown: 2, 6, 8
        return "READY TO SWITCH ON" if state != "QUICK STOP ACTIVE" else state
    if command == 0x07:  # switch on: 3; disable operation: 5
        if state in ("READY TO SWITCH ON", "OPERATION ENABLED"):
            return "SWITCHED ON"
        return state
    if command == 0x0F:  # enable operation: 4, 16 (and 3 + 4)
        if state in ("SWITCHED ON", "READY TO SWITCH ON", "QUICK STOP ACTIVE"):
            return "OPERATION ENABLED"
    return state


class Drive:
    """One drive's firmware around its LocalNode."""

    def __init__(self, node_id, eds, network, log):
        self.id = node_id
        self.node = canopen.LocalNode(node_id, eds)
        network.add_node(self.node)
        self.network, self.log = network, log
        self.state = "SWITCH ON DISABLED"
        self.controlword = 0
        self.position = 0
        # The last RPDO's mapped values, applied at the next SYNC (synchronous RPDO).
        self.received = {}
        self.node.add_read_callback(self.on_read)
        self.node.add_write_callback(self.on_write)
        network.subscribe(0x200 + node_id, self.on_rpdo)
        network.subscribe(0x000, self.on_nmt)

    def value(self, index, sub=0):
        return self.node.sdo.get_variable(index, sub).raw

    def on_nmt(self, can_id, data, timestamp):
        # python-canopen's NMT slave takes reset node and reset communication to
        # Initialising and stops there; CiA 301 has the node reset its communication
        # objects (1000h-1FFFh: 1017h off, the PDOs predefined), send its boot-up and enter
        # Pre-operational by itself.
        if len(data) == 2 and data[0] in (0x81, 0x82) and data[1] in (0, self.id):
            for index in [i for i in self.node.data_store if 0x1000 <= i <= 0x1FFF]:
                del self.node.data_store[index]
            self.node.nmt.send_command(0x82)  # Initialising: the boot-up goes out
            self.node.nmt.send_command(0x80)  # Pre-operational

    def on_read(self, index, subindex, od):
        if index == 0x6041:
            return self.statusword()
        if index == 0x6064:
            return self.position
        if index == 0x6061:
            return self.node.sdo[0x6060].raw
        return None

    def on_write(self, index, subindex, od, data):
        self.log.write(sdo=[self.id, index, subindex, od.decode_raw(data)])
        if index == 0x6040:
            self.command(od.decode_raw(data))

    def statusword(self):
        word = STATUS[self.state] | VOLTAGE_ENABLED | REMOTE
        csp = self.node.sdo[0x6060].raw == MODE_CSP
        if self.state == "OPERATION ENABLED" and csp:
            word |= TARGET_FOLLOWED
        return word

    def command(self, controlword):
        state = next_state(self.state, controlword, self.controlword)
        self.controlword = controlword
        if state != self.state:
            self.state = state
            self.log.write(node=self.id, state=state)

    def mapping(self, index):
        """(index, sub-index, bits) of each entry a mapping object (1600h, 1A00h) holds."""
        entries = []
        for sub in range(1, self.value(index, 0) + 1):
            raw = self.value(index, sub)
            entries.append((raw >> 16, (raw >> 8) & 0xFF, raw & 0xFF))
        return entries

    def valid(self, communication):
        cob_id = self.value(communication, 1)
        return None if cob_id & 0x8000_0000 else cob_id & 0x7FF

    def on_rpdo(self, can_id, data, timestamp):
        if self.node.nmt.state != "OPERATIONAL" or self.valid(0x1400) != can_id:
            return
        offset, values = 0, {}
        for index, sub, bits in self.mapping(0x1600):
            width = bits // 8
            values[(index, sub)] = int.from_bytes(
                data[offset:offset + width], "little", signed=index != 0x6040)
            offset += width
        if offset == len(data):
            self.received = values

    def on_sync(self, sync):
        if self.node.nmt.state != "OPERATIONAL":
            return
        for (index, sub), value in self.received.items():
            if index == 0x6040:
                self.command(value)
            else:
                self.node.sdo.get_variable(index, sub).raw = value
        target = self.node.sdo[0x607A].raw
        csp = self.node.sdo[0x6060].raw == MODE_CSP
        if self.state == "OPERATION ENABLED" and csp:
            self.position = target
        self.log.write(sync=sync, node=self.id, target=target, position=self.position)
        cob_id = self.valid(0x1800)
        if cob_id is None or not 1 <= self.value(0x1800, 2) <= 240:
            return
        data = b""
        for index, sub, bits in self.mapping(0x1A00):
            value = self.node.sdo.get_variable(index, sub).raw
            data += value.to_bytes(bits // 8, "little", signed=index == 0x6064)
        self.network.send_message(cob_id, data)


class Adapter:
    """An slcan (Lawicel) adapter: the host's commands on the terminal, frames to and from
    the bus. `S0`-`S8` set the bit rate and `O` opens the channel while it is closed, `C`
    closes it; `t`/`T` send a frame (answered `z`/`Z` as a CANable does); anything else
    is answered BEL. Every received frame goes to the host as `tIIILDD…` while open."""

    def __init__(self, fd, bus):
        self.fd, self.bus = fd, bus
        self.open = False
        self.bitrate = None
        self.last_byte = time.monotonic()
        self.write_lock = threading.Lock()

    def reply(self, text):
        with self.write_lock:
            os.write(self.fd, text.encode())

    def on_frame(self, message):
        if self.open and not message.is_extended_id:
            self.reply(f"t{message.arbitration_id:03X}{message.dlc}{message.data.hex().upper()}\r")

    def command(self, line):
        if line[:1] == "S" and line[1:] in "012345678" and len(line) == 2 and not self.open:
            self.bitrate = line[1]
            return "\r"
        if line == "O" and not self.open and self.bitrate is not None:
            self.open = True
            return "\r"
        if line == "C" and self.open:
            self.open = False
            return "\r"
        if line[:1] == "t" and self.open and len(line) >= 5:
            can_id, dlc = int(line[1:4], 16), int(line[4])
            data = bytes.fromhex(line[5:5 + 2 * dlc])
            if len(data) == dlc <= 8:
                self.bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))
                return "z\r"
        return "\a"

    def serve(self):
        pending = b""
        while time.monotonic() - self.last_byte < IDLE_EXIT_S:
            try:
                chunk = os.read(self.fd, 4096)
            except BlockingIOError:
                time.sleep(0.0005)
                continue
            except OSError:  # the host closed the terminal
                time.sleep(0.01)
                continue
            self.last_byte = time.monotonic()
            pending += chunk
            while b"\r" in pending:
                line, pending = pending.split(b"\r", 1)
                self.reply(self.command(line.decode(errors="replace")))


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    eds, log_path = sys.argv[1], sys.argv[2]
    log = Log(log_path)
    network = canopen.Network()
    network.connect(interface="virtual", channel=CHANNEL)
    drives = [Drive(node, eds, network, log) for node in NODES]
    syncs = [0]

    def on_sync(can_id, data, timestamp):
        syncs[0] += 1
        for drive in drives:
            drive.on_sync(syncs[0])

    network.subscribe(0x80, on_sync)
    # Power-up: each node boots (the boot-up goes by before the channel opens, as on a bus
    # whose master starts later) and waits in Pre-operational.
    for drive in drives:
        drive.node.nmt.state = "PRE-OPERATIONAL"

    adapter_bus = can.Bus(interface="virtual", channel=CHANNEL)
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    adapter = Adapter(master, adapter_bus)
    notifier = can.Notifier(adapter_bus, [adapter.on_frame])
    print(os.ttyname(slave), flush=True)
    try:
        adapter.serve()
    finally:
        notifier.stop()
        adapter_bus.shutdown()
        network.disconnect()
        os.close(slave)
        os.close(master)


if __name__ == "__main__":
    main()
