"""Independent peer for motus-can's socketcand hub (crates/can/tests/python_interop.rs).

Joins the hub with python-can's own socketcand client, then:
1. sends an RTR request 0x701 (the hub must count and drop it) and a hello frame
   0x7F0 b"hi" (tells the Rust side we are on the bus);
2. for every frame received, prints it as a JSON line and sends back a transformed frame:
   id + 1 (same format), every data byte XOR 0xFF (so lengths 0 and 8 stay 0 and 8);
3. stops after the frame 0x7FF, or when its own timer expires (python-can busy-loops
   when the server closes, so this process must always end by itself).
"""

import argparse
import json
import sys
import time

import can


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--timeout", type=float, default=10.0)
    args = ap.parse_args()
    deadline = time.monotonic() + args.timeout
    bus = can.Bus(interface="socketcand", host="127.0.0.1", port=args.port, channel="can0")
    try:
        bus.send(can.Message(arbitration_id=0x701, is_extended_id=False, is_remote_frame=True, dlc=1))
        bus.send(can.Message(arbitration_id=0x7F0, is_extended_id=False, data=b"hi"))
        while time.monotonic() < deadline:
            msg = bus.recv(timeout=0.2)
            if msg is None:
                continue
            print(json.dumps({
                "id": msg.arbitration_id,
                "extended": msg.is_extended_id,
                "data": msg.data.hex(),
                "timestamp": msg.timestamp,
            }), flush=True)
            mask = 0x1FFFFFFF if msg.is_extended_id else 0x7FF
            reply = can.Message(
                arbitration_id=(msg.arbitration_id + 1) & mask,
                is_extended_id=msg.is_extended_id,
                data=bytes(b ^ 0xFF for b in msg.data),
            )
            bus.send(reply)
            if msg.arbitration_id == 0x7FF and not msg.is_extended_id:
                return 0
        print("timer expired before the end frame 0x7FF", file=sys.stderr)
        return 2
    finally:
        bus.shutdown()


if __name__ == "__main__":
    sys.exit(main())
