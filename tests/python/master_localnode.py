"""python-canopen LocalNode as the independent slave for Motus's CANopen master.

Started by crates/canopen/tests/python_localnode.rs. Joins the Motus socketcand hub,
creates node N from an EDS plus three scratch objects, sends boot-up and heartbeats
(0x1017 = 50 ms) and, on writes to 0x2002 (test command): 1 = send an EMCY
(0x2310, register 0x03, data 01..05), 2 = stop heartbeats, 3 = print the stored values
as JSON on stdout and exit. Ends on its own timer (--lifetime) in any case, because
python-can busy-loops when the server goes away.
"""
import argparse
import json
import struct
import sys
import threading
import time

import canopen
import canopen.objectdictionary as cod


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--eds", required=True)
    ap.add_argument("--node", type=int, default=5)
    ap.add_argument("--lifetime", type=float, default=30.0)
    args = ap.parse_args()

    net = canopen.Network()
    net.connect(interface="socketcand", host="127.0.0.1", port=args.port, channel="can0", tcp_tune=True)
    node = net.create_node(args.node, args.eds)
    od = node.object_dictionary

    def add_var(index, name, data_type, default):
        var = cod.ODVariable(name, index, 0)
        var.data_type = data_type
        var.access_type = "rw"
        var.default = default
        od.add_object(var)

    add_var(0x2000, "Scratch string", cod.VISIBLE_STRING, "initial text of the scratch string")
    add_var(0x2001, "Scratch domain", cod.DOMAIN, b"\x00" * 8)
    add_var(0x2002, "Test command", cod.UNSIGNED8, 0)

    quit_event = threading.Event()

    def on_write(index, subindex, od, data):
        if index != 0x2002:
            return
        cmd = data[0]
        if cmd == 1:
            node.emcy.send(0x2310, 0x03, b"\x01\x02\x03\x04\x05")
        elif cmd == 2:
            node.nmt.stop_heartbeat()
        elif cmd == 3:
            quit_event.set()

    node.add_write_callback(on_write)
    # Producer heartbeat time 50 ms, stored without triggering the 0x1017 callback (it would
    # start heartbeats in the INITIALISING state, which look like boot-ups).
    node.data_store.setdefault(0x1017, {})[0] = struct.pack("<H", 50)

    time.sleep(0.3)  # let the hub's handshake settle
    node.nmt.send_command(0x82)  # reset communication -> boot-up frame 0x700+N [00]
    node.nmt.send_command(0x80)  # pre-operational -> heartbeat every 50 ms

    quit_event.wait(timeout=args.lifetime)
    time.sleep(0.05)  # let the SDO response to the last write leave

    def stored(index):
        try:
            return node.get_data(index, 0).hex()
        except Exception as e:  # noqa: BLE001 - report, the Rust side asserts
            return "error: %s" % e

    print(json.dumps({"%04X" % i: stored(i) for i in (0x2000, 0x2001, 0x6040, 0x607A)}), flush=True)
    node.nmt.stop_heartbeat()
    net.disconnect()
    return 0 if quit_event.is_set() else 2


if __name__ == "__main__":
    sys.exit(main())
