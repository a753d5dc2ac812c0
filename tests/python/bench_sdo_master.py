#!/usr/bin/env python3
"""SDO rate benchmark peer for crates/robot/benches/canopen_rates.rs (issue 5, point 5).

Two roles, both on a Motus socketcand hub on 127.0.0.1:

* ``--role master`` (default): python-canopen's master. ``net.add_node(RemoteNode(N, eds))``
  and expedited uploads of 0x6041:00 (``node.sdo.upload``) in a loop for ``--seconds``;
  prints one JSON line ``{"role": "master", "uploads": .., "errors": .., "seconds": ..,
  "rate_per_s": ..}`` and exits 0 when at least one upload worked. With ``--nodes 20,21,..``
  it uploads from every one of those nodes at once, one thread per node (the same workload
  as Motus's concurrent transfers).
* ``--role localnode``: python-canopen's LocalNode ``net.create_node(N, eds)`` serving SDO
  requests of Motus's master for ``--seconds``; prints ``{"role": "localnode", ...}``.

Either role ends on its own timer (a hard ``os._exit`` after ``--seconds`` + 10 s as well),
because python-can busy-loops when the server goes away.
"""
import argparse
import json
import os
import sys
import threading
import time

import canopen  # a missing package must fail the benchmark, not skip it


def hard_timer(seconds):
    def fire():
        print(json.dumps({"error": "hard timeout"}), flush=True)
        os._exit(3)

    t = threading.Timer(seconds, fire)
    t.daemon = True
    t.start()


def connect(port, tcp_tune):
    net = canopen.Network()
    net.connect(interface="socketcand", host="127.0.0.1", port=port, channel="can0", tcp_tune=tcp_tune)
    time.sleep(0.3)  # let the hub's handshake settle
    return net


def run_master(args):
    net = connect(args.port, args.tcp_tune)
    node = canopen.RemoteNode(args.node, args.eds)
    net.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 0.5
    # Warm-up: first upload (and check the object answers at all).
    node.sdo.upload(0x6041, 0)
    uploads = 0
    errors = 0
    cpu0 = time.process_time()
    start = time.perf_counter()
    deadline = start + args.seconds
    while True:
        now = time.perf_counter()
        if now >= deadline:
            break
        if upload_once(node):
            uploads += 1
        else:
            errors += 1
    elapsed = time.perf_counter() - start
    cpu = time.process_time() - cpu0
    net.disconnect()
    return report_master(args, {"node": args.node}, uploads, errors, elapsed, cpu)


def upload_once(node):
    """One expedited upload of 0x6041:00; True when it returned its 2 bytes."""
    try:
        return len(node.sdo.upload(0x6041, 0)) == 2
    except canopen.SdoError:
        return False


def report_master(args, who, uploads, errors, elapsed, cpu):
    """Prints the master's JSON line; exit status 0 when at least one upload worked.

    ``cpu_s`` is the CPU time of the whole python process (every thread: python-canopen,
    python-can's receive thread) during the timed loop, user and system."""
    line = {"role": "master", **who, "uploads": uploads, "errors": errors}
    line.update(
        {
            "seconds": round(elapsed, 4),
            "rate_per_s": round(uploads / elapsed, 1),
            "cpu_s": round(cpu, 4),
            "tcp_tune": args.tcp_tune,
            "canopen": canopen.__version__,
        }
    )
    print(json.dumps(line), flush=True)
    return 0 if uploads > 0 else 1


def run_master_many(args, nodes):
    """One thread per node, each uploading 0x6041:00 in a loop: python-canopen's master
    with concurrent transfers to several nodes (one SDO client per node)."""
    net = connect(args.port, args.tcp_tune)
    remotes = []
    for n in nodes:
        node = canopen.RemoteNode(n, args.eds)
        net.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 0.5
        node.sdo.upload(0x6041, 0)
        remotes.append(node)
    counts = [[0, 0] for _ in remotes]
    cpu0 = time.process_time()
    start = time.perf_counter()
    deadline = start + args.seconds

    def loop(i, node):
        while time.perf_counter() < deadline:
            counts[i][0 if upload_once(node) else 1] += 1

    threads = [threading.Thread(target=loop, args=(i, node)) for i, node in enumerate(remotes)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    elapsed = time.perf_counter() - start
    cpu = time.process_time() - cpu0
    net.disconnect()
    uploads = sum(c[0] for c in counts)
    return report_master(args, {"nodes": nodes}, uploads, sum(c[1] for c in counts), elapsed, cpu)


def run_localnode(args):
    net = connect(args.port, args.tcp_tune)
    node = net.create_node(args.node, args.eds)
    served = {"n": 0}

    def on_read(index, subindex, od):
        served["n"] += 1
        return None  # the stored / default value is returned

    node.add_read_callback(on_read)
    node.nmt.send_command(0x82)  # reset communication -> boot-up 0x700+N [00]
    node.nmt.send_command(0x80)  # pre-operational
    print(json.dumps({"role": "localnode", "node": args.node, "ready": True}), flush=True)
    time.sleep(args.seconds)
    net.disconnect()
    print(json.dumps({"role": "localnode", "node": args.node, "reads": served["n"]}), flush=True)
    return 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--role", choices=["master", "localnode"], default="master")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--node", type=int, default=2)
    ap.add_argument("--nodes", default="", help="comma-separated nodes: concurrent uploads, one thread each")
    ap.add_argument("--eds", required=True)
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--no-tcp-tune", dest="tcp_tune", action="store_false")
    args = ap.parse_args()
    hard_timer(args.seconds + 10.0)
    if args.role == "master" and args.nodes:
        return run_master_many(args, [int(n) for n in args.nodes.split(",")])
    if args.role == "master":
        return run_master(args)
    return run_localnode(args)


if __name__ == "__main__":
    sys.exit(main())
