#!/usr/bin/env python3
"""Read a whirl Modbus controller's identification and status registers with pymodbus.

An independent third-party client for testing whirl-sim's Modbus server: it shares no code
with whirl's bridge (src/modbus/, src/transport/modbus.rs) nor with tokio-modbus, which
both whirl and whirl-sim use. It reads what docs/modbus.md maps, with function code 03
(read holding registers) and unit id 1, as two requests:

- registers 0-7, the identification block (magic "WH" "RL", map version, slot count, slot
  size, word order, segment rate, watchdog timeout);
- registers 16-34, the status and control block, in one read as the bridge polls it.

It prints one JSON line to stdout and exits 0:

    {"identification": [8 numbers], "status": [19 numbers]}

On an exception answer or no answer it says so on stderr and exits 1.

Written for pymodbus 3.x. The keyword that names the unit id changed between releases
(`unit` in 2.x, `slave` in early 3.x, `device_id` in later ones such as 3.16), so it is
taken from the read method's signature; 2.x keeps its client in pymodbus.client.sync.

Usage: modbus_status.py HOST PORT
"""

import inspect
import json
import sys

from pymodbus.exceptions import ModbusException

try:
    from pymodbus.client import ModbusTcpClient
except ImportError:  # pymodbus 2.x
    from pymodbus.client.sync import ModbusTcpClient

# docs/modbus.md: the unit id the map serves, and the two blocks read.
UNIT_ID = 1
IDENTIFICATION = (0, 8)
STATUS = (16, 19)


def unit_keyword(client):
    """The keyword this pymodbus version's read methods take for the unit id."""
    parameters = inspect.signature(client.read_holding_registers).parameters
    for name in ("device_id", "slave", "unit"):
        if name in parameters:
            return name
    raise SystemExit("this pymodbus has no unit id keyword on read_holding_registers")


def read(client, address, count):
    """`count` holding registers from `address`, or exit 1 on an exception answer."""
    answer = client.read_holding_registers(
        address, count=count, **{unit_keyword(client): UNIT_ID}
    )
    if answer.isError():
        print(f"read {count} registers at {address}: {answer}", file=sys.stderr)
        sys.exit(1)
    return list(answer.registers)


def main():
    if len(sys.argv) != 3:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        sys.exit(2)
    host, port = sys.argv[1], int(sys.argv[2])
    # Every wait is bounded: an unanswered request fails after the timeout, not never.
    client = ModbusTcpClient(host, port=port, timeout=5)
    if not client.connect():
        print(f"cannot connect to {host}:{port}", file=sys.stderr)
        sys.exit(1)
    try:
        result = {
            "identification": read(client, *IDENTIFICATION),
            "status": read(client, *STATUS),
        }
    except ModbusException as e:  # no answer in time, a broken connection
        print(f"{host}:{port}: {e}", file=sys.stderr)
        sys.exit(1)
    finally:
        client.close()
    print(json.dumps(result))


if __name__ == "__main__":
    main()
