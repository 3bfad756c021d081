"""A sharded Relief build on Dask.

    relief.distributed.compress(inputs, archive, client=None, **options)
    python3 -m relief.distributed compress IN... -o OUT [--scheduler ADDR | --workers N]

The build runs the stages of ``relief compress`` as Dask tasks (README,
"Sharded builds"; the files are described in format-spec/shard.md):

    plan       one task: every global parameter, from one pass over the inputs
    partition  one task per input file: its points, snapped, into key-range files
    encode     one task per key range: that range of every input -> a shard archive
    merge      one task: the shards -> one archive

Every task runs the ``relief`` command-line tool (so this module needs no
compiled extension) and writes only files with deterministic names, each under
a temporary name renamed when complete: a task that Dask retries (its worker
died) does its work again and writes the same files. The merged archive holds
the same chunk blobs, byte for byte, as ``relief compress`` of the same inputs
with the same options.

Inputs, the work directory and the archive must be on storage every worker
sees at the same path (a shared file system on a real cluster).

The ``relief`` executable is found, on each worker, from: the ``relief_cli``
argument; the ``RELIEF_CLI`` environment variable; a ``relief`` file next to
this package (an installed layout); the build tree's ``build/tools/relief``
beside the source checkout this file is in; ``relief`` on ``PATH``.
"""

import argparse
import os
import shutil
import signal
import subprocess
import sys
import uuid

__all__ = ["compress", "find_cli", "plan_options", "ReliefCliError"]

_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


class ReliefCliError(RuntimeError):
    """A ``relief`` stage failed. ``exit_code`` is the tool's documented exit
    code (README, "Exit codes": 10 + the stable status code)."""

    def __init__(self, stage, exit_code, message):
        super().__init__("relief %s failed (exit %d): %s" % (stage, exit_code, message))
        self.stage = stage
        self.exit_code = exit_code
        self.detail = message

    def __reduce__(self):
        # Raised on a worker, re-raised on the client: pickled by its fields.
        return (ReliefCliError, (self.stage, self.exit_code, self.detail))


def find_cli(explicit=None):
    """The path of the ``relief`` executable (see the module docstring)."""
    candidates = [explicit, os.environ.get("RELIEF_CLI"),
                  os.path.join(_PACKAGE_DIR, "relief"),
                  os.path.join(_PACKAGE_DIR, os.pardir, os.pardir, "build", "tools", "relief")]
    for c in candidates:
        if c and os.path.isfile(c) and os.access(c, os.X_OK):
            return os.path.abspath(c)
    found = shutil.which("relief")
    if found:
        return found
    raise FileNotFoundError("cannot find the relief executable: set RELIEF_CLI, build it "
                            "(build/tools/relief) or put it on PATH")


def plan_options(options):
    """``relief shard-plan`` arguments for keyword options: ``tolerance=0.002``
    -> ``--tolerance 0.002``, ``chunk_edge=10`` -> ``--chunk-edge 10``,
    ``assume_crs=True`` -> ``--assume-crs`` (False or None: left out). The same
    arguments given to ``relief compress`` make the one-box archive this
    build equals."""
    args = []
    for key in sorted(options):
        value = options[key]
        flag = "--" + key.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            args.append(flag)
        else:
            args += [flag, str(value)]
    return args


def _run(cli, stage, args):
    done = subprocess.run([cli, stage] + args + ["--quiet"], stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        raise ReliefCliError(stage, done.returncode, done.stderr.strip())
    return done.stderr


def _maybe_die(kill_once, stage, index):
    """Test hook: the first time task (stage, index) gets here, kill this worker
    process (SIGKILL, after the task wrote its files but before Dask hears of
    it), so the scheduler must run it again elsewhere. A marker file makes
    "first time" hold across processes."""
    if not kill_once:
        return
    marker_dir, targets = kill_once
    if (stage, index) not in [tuple(t) for t in targets]:
        return
    marker = os.path.join(marker_dir, "killed-%s-%d" % (stage, index))
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return
    os.close(fd)
    os.kill(os.getpid(), signal.SIGKILL)


def _plan_task(cli, inputs, plan_path, args):
    cli = find_cli(cli)
    # The inputs go through a list file: tens of thousands of tile paths do
    # not fit a command line.
    list_path = plan_path + ".inputs"
    with open(list_path, "w", encoding="utf-8") as f:
        for p in inputs:
            if "\n" in p:
                raise ValueError("%r: an input path with a line break cannot be listed" % p)
            f.write(p + "\n")
    _run(cli, "shard-plan", ["--input-list", list_path, "-o", plan_path] + args)
    return read_plan_counts(plan_path)


def _partition_task(cli, plan_path, parts_dir, index, kill_once, _plan):
    cli = find_cli(cli)
    _run(cli, "shard-partition", [plan_path, "--input", str(index), "--dir", parts_dir])
    _maybe_die(kill_once, "partition", index)
    return index


def _encode_task(cli, plan_path, parts_dir, shard_path, index, threads, memory, tmp, kill_once, _partitions):
    cli = find_cli(cli)
    args = [plan_path, "--range", str(index), "--dir", parts_dir, "-o", shard_path, "--threads", str(threads)]
    if memory is not None:
        args += ["--memory", str(memory)]
    if tmp is not None:
        args += ["--tmp", os.path.expandvars(str(tmp))]
    _run(cli, "shard-encode", args)
    _maybe_die(kill_once, "encode", index)
    return shard_path


def _merge_task(cli, shards, merged_path, kill_once, merge_args=()):
    cli = find_cli(cli)
    # A retried merge starts over: its output is a work file, moved into place
    # by the client.
    for suffix in ("", "-wal", "-journal"):
        if os.path.exists(merged_path + suffix):
            os.unlink(merged_path + suffix)
    _run(cli, "merge", list(shards) + ["-o", merged_path] + list(merge_args))
    _maybe_die(kill_once, "merge", 0)
    return merged_path


def read_plan_counts(plan_path):
    """(inputs, ranges) of a plan file (format-spec/shard.md)."""
    inputs = 0
    ranges = None
    with open(plan_path, "r", encoding="utf-8") as f:
        first = f.readline().rstrip("\n").split("\t")
        if first[0] != "relief-shard-plan":
            raise ValueError("%s: not a Relief shard plan" % plan_path)
        for line in f:
            key = line.split("\t", 1)[0].rstrip("\n")
            if key == "input":
                inputs += 1
            elif key == "ranges":
                ranges = int(line.split("\t")[1])
    if ranges is None or inputs == 0:
        raise ValueError("%s: a shard plan without inputs or ranges" % plan_path)
    return inputs, ranges


def compress(inputs, archive, client=None, *, ranges=None, work_dir=None, keep_work=False,
             relief_cli=None, threads_per_task=1, memory_per_task=None, tmp_per_task=None, workers=None,
             _test_kill_once=None,
             _raw_plan_args=None, **options):
    """Builds ``archive`` from ``inputs`` on a Dask cluster.

    client: a ``distributed.Client``; None = a LocalCluster of ``workers``
        worker processes (default: one per core), closed afterwards.
    ranges: key ranges (= stage-2 tasks = shards); None = relief's default
        (about 8 M points each).
    work_dir: where plan, partition files and shards go (shared storage);
        default ``archive + ".work"``, removed afterwards unless keep_work.
    relief_cli: path of the ``relief`` executable on the workers (see find_cli).
    threads_per_task: encoder threads of each stage-2 task.
    memory_per_task: working memory of each stage-2 task, as ``relief
        shard-encode --memory`` takes it (e.g. "2G"); None = its default (1G).
        A key range larger than half of it is sorted through temporary files
        beside its shard (or in ``tmp_per_task``), with the same blobs.
    tmp_per_task: a directory on each worker for those files, e.g. local
        scratch ("$TMPDIR" is expanded on the worker); None = beside the shard.
    options: ``relief compress`` options as keywords (plan_options), e.g.
        tolerance=0.002, chunk_edge=10, columns="x,y,z,i"; ``pyramid`` goes to
        the merge (``relief merge --pyramid``), which builds the pyramid.

    Returns a dict: archive, inputs, ranges, shards. Raises FileExistsError when
    the archive exists (never overwritten), ReliefCliError when a stage fails.
    """
    if isinstance(inputs, (str, bytes, os.PathLike)):
        inputs = [inputs]
    inputs = [os.path.abspath(os.fsdecode(p)) for p in inputs]
    archive = os.path.abspath(archive)
    if not inputs:
        raise ValueError("no input files")
    if os.path.exists(archive):
        raise FileExistsError("%s: already exists (compress never overwrites)" % archive)
    work = os.path.abspath(work_dir) if work_dir else archive + ".work"
    parts = os.path.join(work, "parts")
    os.makedirs(parts, exist_ok=True)
    plan_path = os.path.join(work, "plan.txt")
    # The pyramid is built by the merge, from the merged chunks.
    merge_args = []
    if options.get("pyramid") is not None:
        merge_args = plan_options({"pyramid": options.pop("pyramid")})
    raw = list(_raw_plan_args or [])
    for k, arg in enumerate(raw):
        if arg == "--pyramid" and k + 1 < len(raw):
            merge_args = [arg, raw[k + 1]]
            del raw[k:k + 2]
            break
        if arg.startswith("--pyramid="):
            merge_args = ["--pyramid", arg.split("=", 1)[1]]
            del raw[k]
            break
    args = plan_options(options) + raw
    if ranges is not None:
        args += ["--ranges", str(int(ranges))]

    own_cluster = None
    if client is None:
        from distributed import Client, LocalCluster
        own_cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                                   processes=True, dashboard_address=None)
        client = Client(own_cluster)
    try:
        # Keys unique to this build, so two builds on one cluster never share
        # a result; pure=False: a retried build runs every stage again.
        tag = uuid.uuid4().hex[:12]
        plan = client.submit(_plan_task, relief_cli, inputs, plan_path, args, key="relief-plan-" + tag)
        n_inputs, n_ranges = plan.result()
        partitioned = [client.submit(_partition_task, relief_cli, plan_path, parts, i, _test_kill_once, plan,
                                     key="relief-partition-%d-%s" % (i, tag)) for i in range(n_inputs)]
        shards = [client.submit(_encode_task, relief_cli, plan_path, parts,
                                os.path.join(work, "shard-%04d.relief" % r), r, threads_per_task,
                                memory_per_task, tmp_per_task, _test_kill_once, partitioned,
                                key="relief-encode-%d-%s" % (r, tag))
                  for r in range(n_ranges)]
        merged_path = os.path.join(work, "merged.relief")
        merged = client.submit(_merge_task, relief_cli, shards, merged_path, _test_kill_once, merge_args,
                               key="relief-merge-" + tag)
        merged.result()
    finally:
        if own_cluster is not None:
            client.close()
            own_cluster.close()
    # Into place without ever replacing a file that appeared meanwhile.
    os.link(merged_path, archive)
    os.unlink(merged_path)
    if not keep_work:
        shutil.rmtree(work, ignore_errors=True)
    return {"archive": archive, "inputs": n_inputs, "ranges": n_ranges, "shards": n_ranges}


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python3 -m relief.distributed",
        description="A sharded Relief build on Dask (README, 'Sharded builds'). Options not listed "
                    "here go to 'relief shard-plan' (the options of 'relief compress', e.g. "
                    "--tolerance 0.002 --chunk-edge 10).")
    sub = parser.add_subparsers(dest="command", required=True)
    c = sub.add_parser("compress", help="compress point files into an archive on a Dask cluster")
    c.add_argument("inputs", nargs="+", metavar="IN", help="point files or directories of them")
    c.add_argument("-o", dest="output", required=True, metavar="OUT")
    where = c.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDR", help="a running scheduler, e.g. tcp://host:8786")
    where.add_argument("--workers", type=int, metavar="N", help="a local cluster of N worker processes")
    c.add_argument("--ranges", type=int, metavar="N", help="key ranges = shards (default: ~8 M points each)")
    c.add_argument("--work-dir", metavar="DIR", help="shared work directory (default OUT.work)")
    c.add_argument("--keep-work", action="store_true", help="keep the plan, partition files and shards")
    c.add_argument("--relief-cli", metavar="PATH", help="the relief executable on the workers")
    c.add_argument("--threads-per-task", type=int, default=1, metavar="N")
    c.add_argument("--memory-per-task", metavar="SIZE",
                   help="working memory of each encoding task, e.g. 2G (default 1G; larger key ranges "
                        "are sorted through temporary files)")
    c.add_argument("--tmp-per-task", metavar="DIR",
                   help="where an encoding task puts those files, e.g. local scratch (default: beside its "
                        "shard, in the work directory; $VARS are expanded on the worker)")
    args, plan_args = parser.parse_known_args(argv)
    client = None
    if args.scheduler:
        from distributed import Client
        client = Client(args.scheduler)
    try:
        # Unlisted options pass through verbatim, as 'relief compress' takes them.
        result = compress(args.inputs, args.output, client=client, ranges=args.ranges,
                          work_dir=args.work_dir, keep_work=args.keep_work,
                          relief_cli=args.relief_cli, threads_per_task=args.threads_per_task,
                          memory_per_task=args.memory_per_task, tmp_per_task=args.tmp_per_task,
                          workers=args.workers, _raw_plan_args=plan_args)
    except (ReliefCliError, FileExistsError, FileNotFoundError, ValueError) as e:
        print("relief.distributed: %s" % e, file=sys.stderr)
        return getattr(e, "exit_code", 1)
    finally:
        if client is not None:
            client.close()
    print("%s: %d inputs, %d shards merged" % (result["archive"], result["inputs"], result["shards"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
