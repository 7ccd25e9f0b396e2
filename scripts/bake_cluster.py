#!/usr/bin/env python3
"""Bakes a tile mosaic's package set on a Dask cluster: one task a cell of the tiles' lattice.

`clipsat bake --terrain TILES --parts DIR` bakes a package set on one machine. This script spreads the
same bake over a Dask cluster (`dask.distributed`) in three steps:
  1. here: `clipsat bake --terrain TILES --parts DIR --list-cells --json` lists the cells and says which
     parts are baked already;
  2. the map step, on the workers: one task a cell not baked (every cell with --all), each running
     `clipsat bake --terrain TILES --parts DIR --cell N --json` as a subprocess; a line is printed as
     each cell finishes (the cell, its seconds, the worker that baked it, the part's bytes);
  3. the reduce step, here: `clipsat bake --terrain TILES --parts DIR --finish --json` bakes the top
     package and writes the index DIR/clipsat-set.toml, which `clipsat ... --terrain DIR` opens.
A part's bytes depend on its tiles and the bake's options alone, not on the machine, worker or order
that bakes it, so the set is bit-equal to the one `clipsat bake --parts DIR` writes. A killed run
resumes when run again: the parts already baked are kept (--all bakes them again).

Usage:
  scripts/bake_cluster.py --terrain TILES --parts DIR [--clipsat BIN] [--workers N | --scheduler ADDR]
                          [--all] [-- CLIPSAT-BAKE-OPTIONS...]
Arguments after `--` go to every `clipsat bake` call, e.g. `-- --fill-height 0 --max-error 1`; give
paths in them as absolute paths.

On one machine (a LocalCluster of N single-threaded workers, default the CPU count; each bake uses up
to 8 of the machine's cores itself, so N below the core count often does as well):
  python3 scripts/bake_cluster.py --clipsat target/release/clipsat --terrain /data/srtm \\
      --parts /data/set --workers 2 -- --fill-height 0

On a real cluster: every worker runs the binary, reads the tiles and writes DIR at the same paths as
the machine that runs this script, so those live on a shared filesystem (NFS, Lustre, ...), and the
workers run the same Python and dask versions as this script. Start a scheduler, then workers (one
single-threaded worker a machine lets each bake use the machine's cores), then this script:
  dask scheduler --port 8786                                       # on host H
  dask worker tcp://H:8786 --nworkers 1 --nthreads 1               # on each worker machine
  python3 scripts/bake_cluster.py --scheduler tcp://H:8786 --clipsat /shared/bin/clipsat \\
      --terrain /shared/srtm --parts /shared/set -- --fill-height 0
On SLURM, PBS, SGE or LSF, the workers run as batch jobs: submit `dask worker tcp://H:8786 --nthreads 1`
in jobs that book the cores a bake uses (e.g. `sbatch --cpus-per-task 8`), or let dask-jobqueue
(https://jobqueue.dask.org) submit them: in a Python session that stays open while the script runs,
`cluster = SLURMCluster(cores=1, processes=1, job_cpu=8, memory="2GB"); cluster.scale(jobs=16)`
(PBSCluster and the others alike), and give `cluster.scheduler_address` as --scheduler.

Exit status: 0 the set is baked; 1 a cell or the finish failed (the failing command and its stderr are
printed; the other cells' tasks are cancelled and their bakes stopped); 2 bad arguments (including a
TILES or option that `--list-cells` refuses, and dask.distributed missing:
pip install 'dask[distributed]'); 130 interrupted (Ctrl-C; the bakes running are stopped).
Requires Python 3.11 and dask.distributed; nothing else outside the standard library.
"""

import argparse
import json
import logging
import os
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import uuid


def bake_cell(cmd, cell, stop_name):
    """Runs one cell's bake (`cmd`) as a subprocess on a worker; stops it when the Event `stop_name` is
    set (another cell failed). Returns the cell, its status, output and seconds, and where it ran."""
    from distributed import Event, get_worker

    start = time.monotonic()
    stop = Event(stop_name)
    # Its own process group, so that a stop ends the bake and anything it started (a wrapper's children).
    with subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    ) as proc:
        # Output read on threads, so that a full pipe never stalls the bake while it is polled.
        out = {}

        def drain(name, stream):
            out[name] = stream.read()

        readers = [
            threading.Thread(target=drain, args=("stdout", proc.stdout)),
            threading.Thread(target=drain, args=("stderr", proc.stderr)),
        ]
        for r in readers:
            r.start()
        stopped = False
        while True:
            try:
                proc.wait(timeout=1.0)
                break
            except subprocess.TimeoutExpired:
                if not stopped and stop.is_set():
                    try:
                        os.killpg(proc.pid, signal.SIGTERM)
                    except ProcessLookupError:
                        pass
                    stopped = True
        for r in readers:
            r.join()
    try:
        worker = get_worker().address
    except ValueError:
        worker = "?"
    return {
        "cell": cell,
        "cmd": cmd,
        "returncode": proc.returncode,
        "stdout": out.get("stdout", ""),
        "stderr": out.get("stderr", ""),
        "seconds": time.monotonic() - start,
        "worker": f"{worker} ({socket.gethostname()})",
    }


def shell(cmd):
    """`cmd` as one shell line, for messages."""
    return shlex.join(cmd)


def run_json(cmd, what):
    """Runs `cmd` here; returns its JSON stdout, or None after printing why it failed."""
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        print(f"bake_cluster: {what} failed (exit {p.returncode}): {shell(cmd)}", file=sys.stderr)
        sys.stderr.write(p.stderr)
        return None
    try:
        return json.loads(p.stdout)
    except json.JSONDecodeError as e:
        print(f"bake_cluster: {what} printed no JSON ({e}): {shell(cmd)}", file=sys.stderr)
        return None


def parse(argv):
    """The script's arguments and the `clipsat bake` arguments after `--`."""
    extra = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1 :]
    ap = argparse.ArgumentParser(
        prog="bake_cluster.py",
        description="Bake a tile mosaic's package set on a Dask cluster, one task a cell "
        "(`clipsat bake --parts DIR --cell N`), then its top and index here (`--finish`). "
        "Arguments after `--` go to every `clipsat bake` call.",
        epilog="Workers need the binary, the tiles and DIR at the same paths (a shared filesystem). "
        "See the module docstring for running on a real cluster.",
    )
    ap.add_argument(
        "--clipsat", default="clipsat", metavar="PATH", help="the clipsat binary (default: clipsat on PATH)"
    )
    ap.add_argument(
        "--terrain",
        required=True,
        metavar="TILES",
        help="the tile mosaic: a folder, .txt list, .vrt or quoted glob",
    )
    ap.add_argument("--parts", required=True, metavar="DIR", help="the package set's folder")
    ap.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="an existing `dask scheduler`'s address, e.g. tcp://host:8786 (default: a LocalCluster)",
    )
    ap.add_argument(
        "--workers",
        type=int,
        default=os.cpu_count() or 1,
        metavar="N",
        help="the LocalCluster's single-threaded workers (default: the CPU count)",
    )
    ap.add_argument("--all", action="store_true", help="bake every cell again, not only those not baked")
    args = ap.parse_args(argv)
    if args.workers < 1:
        ap.error("--workers must be at least 1")
    if args.scheduler and any(a == "--workers" or a.startswith("--workers=") for a in argv):
        ap.error("--workers sizes the LocalCluster: give it or --scheduler, not both")
    binary = shutil.which(args.clipsat)
    if binary is None:
        ap.error(f"--clipsat {args.clipsat}: no such executable")
    # Absolute paths: the workers' current folders may differ from this one's.
    args.clipsat = os.path.abspath(binary)
    args.terrain = os.path.abspath(args.terrain)
    args.parts = os.path.abspath(args.parts)
    return args, extra


def main(argv):
    args, extra = parse(argv)
    try:
        import distributed
    except ImportError:
        print("bake_cluster: dask.distributed is missing: pip install 'dask[distributed]'", file=sys.stderr)
        return 2
    wall = time.monotonic()
    base = [args.clipsat, "bake", "--terrain", args.terrain, "--parts", args.parts, *extra]
    listed = run_json([*base, "--list-cells", "--json"], "listing the cells")
    if listed is None:
        return 2
    cells = listed["list"]
    todo = [c["cell"] for c in cells if args.all or not c["baked"]]
    print(
        f"{len(cells)} cells, {len(todo)} to bake, {len(cells) - len(todo)} kept "
        f"(tiles of {listed['tile']}^2, {listed['part_levels']} levels a part)",
        flush=True,
    )
    if todo:
        failed = bake_cells(distributed, args, base, todo)
        if failed is not None:
            return 1
    bake = time.monotonic() - wall
    done = run_json([*base, "--finish", "--json"], "the finish (the top and the index)")
    if done is None:
        return 1
    print(
        f"set {done['set']}: {len(cells)} cells ({len(todo)} baked, {len(cells) - len(todo)} kept), "
        f"{done['bytes']} bytes, {done['removed']} stale files removed; "
        f"wall {time.monotonic() - wall:.1f} s (cells {bake:.1f} s, finish {done['seconds']:.1f} s)"
    )
    return 0


def bake_cells(distributed, args, base, todo):
    """Bakes the cells `todo` on the cluster; returns None, or the first failed cell's result."""
    cluster = None
    if args.scheduler:
        client = distributed.Client(args.scheduler)
        where = args.scheduler
    else:
        cluster = distributed.LocalCluster(
            n_workers=args.workers,
            threads_per_worker=1,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        )
        client = distributed.Client(cluster)
        where = f"a LocalCluster of {args.workers} single-threaded workers"
    stop_name = f"bake-cluster-stop-{uuid.uuid4().hex}"
    stop = distributed.Event(stop_name, client=client)
    failed = None
    try:
        print(f"baking {len(todo)} cells on {where}", flush=True)
        futures = [
            client.submit(
                bake_cell,
                [*base, "--cell", str(n), "--json"],
                n,
                stop_name,
                pure=False,
                key=f"bake-cell-{n}-{uuid.uuid4().hex[:8]}",
            )
            for n in todo
        ]
        finished = 0
        for f in distributed.as_completed(futures):
            try:
                r = f.result()
            except Exception as e:  # the task itself raised, or its worker died too often
                r = {
                    "cell": todo[futures.index(f)],
                    "cmd": None,
                    "returncode": None,
                    "stdout": "",
                    "stderr": f"{type(e).__name__}: {e}\n",
                    "worker": "?",
                }
            if r["returncode"] != 0:
                failed = r
                break
            finished += 1
            try:
                part = json.loads(r["stdout"]).get("bytes", "?")
            except json.JSONDecodeError:
                part = "?"
            print(
                f"[{finished}/{len(todo)}] cell {r['cell']}: {r['seconds']:.1f} s "
                f"on {r['worker']}, {part} bytes",
                flush=True,
            )
        if failed is not None:
            stop.set()
            client.cancel([f for f in futures if not f.done()])
            cmd = shell(failed["cmd"] or [*base, "--cell", str(failed["cell"]), "--json"])
            print(
                f"bake_cluster: cell {failed['cell']} failed (exit {failed['returncode']}) "
                f"on {failed['worker']}: {cmd}",
                file=sys.stderr,
            )
            sys.stderr.write(failed["stderr"])
            print(
                "bake_cluster: the other cells' tasks are cancelled; run again to resume "
                "(the parts baked are kept)",
                file=sys.stderr,
            )
            # Let the running bakes see the stop before the workers go.
            time.sleep(1.5)
    except KeyboardInterrupt:
        stop.set()
        print("bake_cluster: interrupted; stopping the bakes (run again to resume)", file=sys.stderr)
        time.sleep(1.5)
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return failed


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except KeyboardInterrupt:
        sys.exit(130)
