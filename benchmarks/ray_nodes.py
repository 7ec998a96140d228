"""A sweep on a Ray cluster of one node, then two, started on this machine: the scaling per node.

    python benchmarks/ray_nodes.py --json                 # about 3 minutes on 2 idle cores
    python benchmarks/ray_nodes.py --json --repeats 2     # 1, 2, 1, 2 nodes, alternating

Starts a head node (``ray start --head --num-cpus 1``) and runs ``marine-fdi sweep --agents all
--suites all --backend ray --ray-address 127.0.0.1:PORT --workers 2 --cache off`` on it; adds a
second node (``ray start --address 127.0.0.1:PORT --num-cpus 1``) and runs the sweep again; with
``--repeats`` removes the second node and starts over.  Each node has one CPU, so one task runs
per node.  At the end it stops the nodes it started (their processes, by id; never ``ray stop``,
which stops every Ray instance of the user on the machine).  Prints one JSON object: wall time
and 1-minute load average before and after each sweep (``one_node``, ``two_nodes``), their
medians, ``speedup`` (one-node over two-node median), and whether every table is the same record
for record outside the wall-clock fields (``tables_equal``).  ``two_process_throughput``: what the
machine gives two CPU-bound processes at once over one alone, measured just before (a Python loop
of about 2 s, run alone and then twice in parallel, at this script's priority): 2.0 on two free
cores; on a shared machine it bounds what a second node can add.  ``--keep`` keeps the sweeps' folders
(docs/data/sweep/ holds the table and run records of one such run).

This machine needs two settings a real cluster may not: ``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=1``
(Ray refuses a second node on a machine whose nodes share an address otherwise) and
``--node-ip-address 127.0.0.1`` (Ray would advertise the machine's network address, which the
sandbox does not let a process connect to); Ray 2.5x also starts clusters with token
authentication, so the driver runs with ``RAY_AUTH_MODE=token`` (the token in ``~/.ray/auth_token``).
Both nodes share the machine's two cores with whatever else runs on it: the load is printed.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _report import emit  # noqa: E402  (benchmarks/ is the script directory)

ENV = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "1", "RAY_AUTH_MODE": "token"}


def _pids(marker: str) -> set[int]:
    """Processes whose command line holds ``marker`` (the cluster's temporary folder), and their children."""
    rows = [
        ln.split(None, 2)
        for ln in subprocess.run(["ps", "-eo", "pid,ppid,args"], capture_output=True, text=True).stdout.splitlines()[1:]
    ]
    found = {int(p) for p, _, args in (r + [""] * (3 - len(r)) for r in rows) if marker in args}
    grown = True
    while grown:
        kids = {int(p) for p, pp, *_ in rows if int(pp) in found} - found
        grown = bool(kids)
        found |= kids
    return found - {os.getpid()}


def _stop(pids: set[int]) -> None:
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for p in pids:
            try:
                os.kill(p, sig)
            except ProcessLookupError:
                pass
        time.sleep(3)


_SPIN = (
    "import time; t = time.perf_counter(); x = 0\nfor i in range(30_000_000): x += i\nprint(time.perf_counter() - t)"
)


def _two_process_throughput() -> float:
    """Throughput of two CPU-bound processes at once over one alone (2.0 on two free cores)."""

    def spin(k: int) -> float:
        procs = [subprocess.Popen([sys.executable, "-c", _SPIN], stdout=subprocess.PIPE, text=True) for _ in range(k)]
        return max(float(p.communicate()[0]) for p in procs)

    one = spin(1)
    return round(2 * one / spin(2), 2)


def _ray(args: list[str]) -> None:
    proc = subprocess.run(
        [str(Path(sys.executable).with_name("ray")), *args, "--disable-usage-stats"],
        env=dict(os.environ, **ENV),
        capture_output=True,
        text=True,
        timeout=300,
    )
    if proc.returncode != 0:
        raise SystemExit(f"ray {' '.join(args)} failed:\n{proc.stderr[-2000:]}")


def _nodes(address: str) -> int:
    """The cluster's live nodes."""
    out = subprocess.run(
        [
            sys.executable,
            "-c",
            "import ray, json; ray.init(address=%r, logging_level='ERROR'); "
            "print(json.dumps(len([n for n in ray.nodes() if n['Alive']])))" % address,
        ],
        env=dict(os.environ, **ENV),
        capture_output=True,
        text=True,
        timeout=120,
    )
    return int(out.stdout.strip().splitlines()[-1])


def speed_sweep(address: str, out: Path, cwd: Path) -> dict:
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "marine_fdi_env.cli",
            "sweep",
            "--agents",
            "all",
            "--suites",
            "all",
            "--backend",
            "ray",
            "--ray-address",
            address,
            "--workers",
            "2",
            "--cache",
            "off",
            "--out",
            str(out),
            "--no-progress",
        ],
        cwd=cwd,
        env=dict(os.environ, **ENV),
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"the sweep failed:\n{proc.stderr[-2000:]}")
    return {
        "wall_s": round(wall, 2),
        "load_before": round(load0, 2),
        "load_after": round(os.getloadavg()[0], 2),
        "sweep_wall_s": round(json.loads((out / "sweep.json").read_text())["wall_s"], 2),
    }


def _same_tables(folders: list[Path]) -> bool:
    from marine_fdi_env.benchmark.evaluate import WALL_CLOCK_FIELDS
    from marine_fdi_env.benchmark.records import read_records

    tables = [
        [
            {k: v for k, v in r.items() if k not in WALL_CLOCK_FIELDS}
            for r in read_records(f / "episodes.parquet", keep_extra=True)[0]
        ]
        for f in folders
    ]
    return all(t == tables[0] for t in tables[1:])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--port", type=int, default=6399)
    ap.add_argument("--repeats", type=int, default=1, help="one-node / two-node rounds")
    ap.add_argument("--keep", action="store_true", help="keep the sweeps' folders (printed as 'folder')")
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="marine-fdi-ray-"))
    address = f"127.0.0.1:{args.port}"
    node = ["--num-cpus", "1", "--node-ip-address", "127.0.0.1"]
    runs: dict[str, list] = {"one_node": [], "two_nodes": []}
    folders = []
    capacity = _two_process_throughput()
    try:
        _ray(
            [
                "start",
                "--head",
                "--port",
                str(args.port),
                "--temp-dir",
                str(tmp / "ray"),
                "--include-dashboard",
                "false",
                *node,
            ]
        )
        head = _pids(str(tmp / "ray"))
        for r in range(args.repeats):
            if _nodes(address) != 1:
                raise SystemExit("the cluster should have one node here")
            folders.append(tmp / f"one{r}")
            runs["one_node"].append(speed_sweep(address, folders[-1], tmp))
            _ray(["start", "--address", address, *node])
            if _nodes(address) != 2:
                raise SystemExit("the second node did not join")
            folders.append(tmp / f"two{r}")
            runs["two_nodes"].append(speed_sweep(address, folders[-1], tmp))
            if r + 1 < args.repeats:  # remove the second node; the head notices within about a minute
                _stop(_pids(str(tmp / "ray")) - head)
                deadline = time.monotonic() + 180
                while _nodes(address) != 1 and time.monotonic() < deadline:
                    time.sleep(5)
        same = _same_tables(folders)
    finally:
        _stop(_pids(str(tmp / "ray")))
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)
    one = statistics.median(x["wall_s"] for x in runs["one_node"])
    two = statistics.median(x["wall_s"] for x in runs["two_nodes"])
    emit(
        {
            "cpu_count": os.cpu_count(),
            "episodes": 3672,
            "folder": str(tmp) if args.keep else None,
            **runs,
            "two_process_throughput": capacity,
            "one_node_s": one,
            "two_nodes_s": two,
            "speedup": round(one / two, 2),
            "tables_equal": same,
        },
        args.json,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
