#!/usr/bin/env python3
"""python-canopen's BaseNode402 master against the Motus IclA simulator (motus-icla-sim).

Run by crates/icla-sim/tests/python_interop.rs over a Motus socketcand hub:
  icla_402_master.py --port P --node N --eds FILE [--timeout S]
Prints one `KEY value` line per result; exits 0 only when every step worked. Ends on its own
timer (python-can busy-loops when the server closes).
"""
import argparse
import os
import sys
import threading
import time

import canopen  # a missing package must fail the test, not skip it
from canopen.profiles.p402 import BaseNode402
from canopen.sdo import SdoAbortedError


def out(key, value):
    print(f"{key} {value}", flush=True)


def wait_bits(node, mask, value, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            sw = node.check_statusword()
        except RuntimeError:
            sw = node.sdo[0x6041].raw
        if sw & mask == value:
            return sw
    raise RuntimeError(f"statusword bits {mask:#06x} != {value:#06x} (last {node.statusword:#06x})")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--node", type=int, required=True)
    ap.add_argument("--eds", required=True)
    ap.add_argument("--timeout", type=float, default=40.0)
    args = ap.parse_args()
    timer = threading.Timer(args.timeout, lambda: (print("TIMEOUT", flush=True), os._exit(3)))
    timer.daemon = True
    timer.start()

    net = canopen.Network()
    net.connect(interface="socketcand", host="127.0.0.1", port=args.port, channel="can0")
    node = BaseNode402(args.node, args.eds)
    net.add_node(node)

    # NMT: a heartbeat tells the state (the simulator's default period is 1000 ms).
    node.nmt.wait_for_heartbeat(timeout=3)
    out("NMT_STATE", node.nmt.state)

    # SDO: expedited and segmented uploads, a download read back, an abort.
    out("DEVICE_TYPE", f"0x{node.sdo[0x1000].raw:08X}")
    out("DEVICE_NAME", node.sdo[0x1008].raw)
    out("VENDOR", f"0x{node.sdo[0x1018][1].raw:08X}")
    out("SERIAL", node.sdo[0x1018][4].raw)
    node.sdo[0x6081].raw = 300
    out("PROFILE_VELOCITY", node.sdo[0x6081].raw)
    try:
        node.sdo[0x6041].raw = 1
        out("ABORT", "none")
    except SdoAbortedError as e:
        out("ABORT", f"0x{e.code:08X}")

    # PDO configuration: read, change TPDO1's event timer, save, read back.
    node.tpdo.read()
    node.rpdo.read()
    out("TPDO1_MAP", ",".join(f"0x{v.index:04X}" for v in node.tpdo[1].map))
    out("RPDO2_MAP", ",".join(f"0x{v.index:04X}" for v in node.rpdo[2].map))
    node.tpdo[1].event_timer = 20
    node.tpdo.save()
    node.rpdo.save()
    out("TPDO1_EVENT_TIMER", node.sdo[0x1800][5].raw)

    node.setup_402_state_machine(read_pdos=True)
    node.nmt.state = "OPERATIONAL"
    time.sleep(0.1)
    node.state = "SWITCH ON DISABLED"
    node.state = "OPERATION ENABLED"
    out("STATE", node.state)

    node.op_mode = "PROFILED POSITION"
    out("MODE", node.op_mode)

    # Profile position by hand: target, new set-point, wait bit 12, release, wait bit 10.
    start = node.sdo[0x6064].raw
    node.sdo[0x607A].raw = start + 213
    node.controlword = 0x1F
    wait_bits(node, 0x1000, 0x1000, 1.0)
    node.controlword = 0x0F
    wait_bits(node, 0x1400, 0x0400, 5.0)
    out("POSITION", node.sdo[0x6064].raw - start)

    # TPDO2 (statusword + position) comes with a SYNC.
    net.sync.transmit()
    node.tpdo[2].wait_for_reception(1.0)
    out("TPDO2_POSITION", node.tpdo[2]["Position actual value"].raw - start)

    # Homing on the current position with a home offset.
    node.sdo[0x6098].raw = 35
    node.sdo[0x607C].raw = 100
    out("HOMED", node.homing(timeout=5))
    out("HOMED_POSITION", node.sdo[0x6064].raw)

    node.state = "SWITCH ON DISABLED"
    out("FINAL_STATE", node.state)
    net.disconnect()
    out("DONE", "ok")
    os._exit(0)


if __name__ == "__main__":
    try:
        main()
    except Exception as e:  # report and fail
        print(f"ERROR {type(e).__name__}: {e}", flush=True)
        os._exit(1)
