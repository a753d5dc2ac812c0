#!/usr/bin/env python3
"""python-canopen's LssMaster against LSS-unconfigured Motus IclA simulators.

Run by crates/icla-sim/tests/python_interop.rs over a Motus socketcand hub with three
unconfigured drives (serial numbers 1, 2, 3):
  icla_lss.py --port P [--timeout S]
Fastscan finds serial 1 -> node 2 (with bit timing 20 kbit/s activated), selective switch
on serial 2 -> node 3, fastscan again finds serial 3 -> node 4; then SDO reads each node's
serial number. Prints `KEY value` lines; exits 0 only when every step worked.
"""
import argparse
import os
import threading
import time

import canopen  # a missing package must fail the test, not skip it

WAITING, CONFIGURATION = 0, 1


def out(key, value):
    print(f"{key} {value}", flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--timeout", type=float, default=90.0)
    args = ap.parse_args()
    timer = threading.Timer(args.timeout, lambda: (print("TIMEOUT", flush=True), os._exit(3)))
    timer.daemon = True
    timer.start()

    net = canopen.Network()
    net.connect(interface="socketcand", host="127.0.0.1", port=args.port, channel="can0")
    bootups = []
    for n in (2, 3, 4):
        net.subscribe(0x700 + n, lambda can_id, data, ts: data[:1] == b"\x00" and bootups.append((can_id, bytes(data))))
    lss = net.lss
    time.sleep(0.2)

    # Identify non-configured remote slaves: every unconfigured drive answers 0x50.
    lss.send_identify_non_configured_remote_slave()
    time.sleep(0.3)
    answers = []
    while not lss.responses.empty():
        answers.append(lss.responses.get()[0])
    out("NON_CONFIGURED", sum(1 for cs in answers if cs == 0x50))

    ok, ids = lss.fast_scan()
    out("FASTSCAN1", f"{ok} " + " ".join(f"0x{x:08X}" for x in (ids or [])))
    vendor, product, revision = ids[0], ids[1], ids[2]
    out("INQUIRE_VENDOR", f"0x{lss.inquire_lss_address(0x5A):08X}")
    out("INQUIRE_PRODUCT", f"0x{lss.inquire_lss_address(0x5B):08X}")
    out("INQUIRE_REVISION", f"0x{lss.inquire_lss_address(0x5C):08X}")
    out("INQUIRE_SERIAL", lss.inquire_lss_address(0x5D))
    out("INQUIRE_NODE_ID_BEFORE", lss.inquire_node_id())
    lss.configure_node_id(2)
    lss.configure_bit_timing(7)
    lss.store_configuration()
    lss.activate_bit_timing(50)
    time.sleep(0.15)
    lss.send_switch_state_global(WAITING)
    time.sleep(0.3)

    found = lss.send_switch_state_selective(vendor, product, revision, 2)
    out("SELECTIVE2", found)
    lss.configure_node_id(3)
    lss.store_configuration()
    lss.send_switch_state_global(WAITING)
    time.sleep(0.3)

    ok, ids = lss.fast_scan()
    out("FASTSCAN2", f"{ok} " + " ".join(f"0x{x:08X}" for x in (ids or [])))
    lss.configure_node_id(4)
    lss.store_configuration()
    out("INQUIRE_NODE_ID_PENDING", lss.inquire_node_id())
    lss.send_switch_state_global(WAITING)
    time.sleep(0.3)

    out("BOOTUPS", " ".join(f"{cid:03X}#{data.hex().upper()}" for cid, data in sorted(bootups)))
    for n in (2, 3, 4):
        node = canopen.RemoteNode(n, canopen.ObjectDictionary())
        net.add_node(node)
        serial = int.from_bytes(node.sdo.upload(0x1018, 4), "little")
        out(f"NODE{n}_SERIAL", serial)
    net.disconnect()
    out("DONE", "ok")
    os._exit(0)


if __name__ == "__main__":
    try:
        main()
    except Exception as e:
        print(f"ERROR {type(e).__name__}: {e}", flush=True)
        os._exit(1)
