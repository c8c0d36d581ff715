"""Command line: impactfv run | check | compare | plot.

Exit codes: 0 success, 2 input error (one line, no traceback), 3 failed simulation,
130/143 interrupted, 141 the output pipe was closed by its reader.

Only the standard library and the light modules below are imported here: the signal
handlers are installed first thing in :func:`main`, before numpy, numba and the case schema
load (a Ctrl-C at any moment gives exit 130 and one line, never a traceback).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from . import interrupts
from .version import __version__
from .errors import InputError, Interrupted, SimulationError, printable


DESCRIPTION = ("Transient large-strain solid dynamics with contact by an upwind "
               "vertex-centred finite volume method.")
EPILOG = ("exit codes: 0 success, 2 bad input (one line naming the key or file), 3 the "
          "simulation failed, 130/143 interrupted (a checkpoint was written), 141 the reader "
          "of the output went away")


class _Parser(argparse.ArgumentParser):
    """Usage errors on one line, like every other input error (exit code 2)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    # after the subcommand as well as before it; SUPPRESS keeps the first one's value
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show tracebacks instead of one-line errors")
    overrides = argparse.ArgumentParser(add_help=False)
    overrides.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                           dest="overrides",
                           help="change a key of the case, e.g. run.end_time=3e-4 or "
                                "body[0].velocity=[10,0] (a TOML value; repeatable)")
    parser = _Parser(prog="impactfv", description=DESCRIPTION, epilog=EPILOG)
    parser.add_argument("--version", action="version", version=f"impactfv {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show tracebacks instead of one-line errors")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                parser_class=_Parser)
    p_run = sub.add_parser("run", parents=[common, overrides], help="run a case file",
                           description="Run a case file and write its results.")
    p_run.add_argument("case", help="TOML case file")
    p_run.add_argument("-o", "--output", help="output folder (default results/<case stem>)")
    p_run.add_argument("--no-progress", action="store_true", help="no progress bar")
    p_run.add_argument("--overwrite", action="store_true",
                       help="start afresh in an output folder that impactfv did not make or "
                            "that holds checkpoints (deleting the earlier run's outputs)")
    p_run.add_argument("--restart", metavar="DIR",
                       help="continue the run in DIR from its newest checkpoint")
    p_run.add_argument("--checkpoint-every", metavar="T", type=_positive_float,
                       help="write a checkpoint every T seconds of simulated time")
    p_run.add_argument("--plot", action="store_true",
                       help="also write PNG quick-look pictures (as impactfv plot)")
    p_run.add_argument("--threads", metavar="N", type=_positive_int,
                       help="CPU threads of the kernels (as run.threads; default: the cores "
                            "this process may use)")
    p_run.add_argument("--backend", choices=("cpu", "cuda"),
                       help="where the FV kernels run (as run.backend; default cpu)")
    p_check = sub.add_parser("check", parents=[common, overrides],
                             help="check a case: mesh, wave speeds, time step, memory",
                             description="Check a case and report its meshes, wave speeds, "
                                         "time step, memory and overlaps; run nothing.")
    p_check.add_argument("case", help="TOML case file")
    p_check.add_argument("--ranks", metavar="N", type=_positive_int,
                         help="also report the partition over N MPI ranks (nodes, halo nodes "
                              "and cut edges per rank)")
    p_cmp = sub.add_parser("compare", parents=[common, overrides],
                           help="run the FV and FE methods on a case and compare",
                           description="Run the FV scheme and the FE baselines that can run "
                                       "the case, and compare them (figures and a table).")
    p_cmp.add_argument("case", help="TOML case file")
    p_cmp.add_argument("-o", "--output", help="output folder (default results/<stem>_compare)")
    p_plot = sub.add_parser("plot", parents=[common],
                            help="PNG pictures of a result folder (no ParaView needed)",
                            description="Write PNG quick-look pictures of a result folder: a "
                                        "field on the deformed bodies at chosen times, and the "
                                        "history curves.")
    p_plot.add_argument("results", metavar="RESULT_DIR", help="folder written by impactfv run")
    p_plot.add_argument("--field", default="pressure",
                        help="field to draw (default pressure); a vector gives its magnitude, "
                             "a suffix a component: velocity_x, stress_xy")
    p_plot.add_argument("--times", metavar="T1,T2,...",
                        help="times in seconds (the nearest frames are drawn); default: four "
                             "frames from the first to the last")
    p_plot.add_argument("-o", "--output", help="folder of the pictures (default "
                                               "RESULT_DIR/plots)")
    return parser


def main(argv=None) -> int:
    interrupts.install()
    parser = _parser()
    args = parser.parse_args(argv)
    from .parallel.comm import end_together
    try:
        code = _main(args)
    except Exception:
        # a bug: its traceback, and under mpiexec the other ranks must not wait for this one
        import traceback
        traceback.print_exc()
        end_together(1)
        return 1
    if code:
        end_together(code)        # under mpiexec: every rank stops, or the job is aborted
    return code


def _main(args) -> int:
    try:
        _only_rank_0_reports()
        if args.command == "run":
            return _run(args)
        if args.command == "check":
            return _check(args)
        if args.command == "compare":
            from .compare import compare_main
            return compare_main(args)
        if args.command == "plot":
            from .plot import plot_main
            return plot_main(args)
    except InputError as exc:
        if args.debug:
            raise
        print(f"impactfv: error: {printable(exc)}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        if args.debug:
            raise
        print(f"impactfv: simulation failed: {printable(exc)}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print("impactfv: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of our output went away (`impactfv check case.toml | head -1`): stop
        # quietly like a tool killed by SIGPIPE; results already written stay as they are
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except Interrupted as exc:
        print(f"impactfv: {printable(exc)}; continue with --restart", file=sys.stderr)
        return 128 + int(exc.signum)
    except MemoryError:
        if args.debug:
            raise
        print("impactfv: error: out of memory: the case needs more memory than this machine "
              "has available (impactfv check case.toml reports the estimate); use a coarser "
              "mesh", file=sys.stderr)
        return 2
    return 0


def _only_rank_0_reports():
    """Under mpiexec every rank runs the same command and would print the same lines: only
    rank 0 prints (the others run silently alongside; their exit codes are the same)."""
    from .parallel.comm import launched_size, rank

    if launched_size() > 1 and rank() != 0:
        sys.stdout = sys.stderr = open(os.devnull, "w")


def _positive_float(text):
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive time in seconds, got {text!r}")
    return value


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text!r}")
    return value


def _run(args) -> int:
    from .case import load_case
    from .pipeline import run

    overrides = list(args.overrides)
    if args.threads is not None:
        overrides.append(f"run.threads={args.threads}")
    if args.backend is not None:
        overrides.append(f"run.backend={args.backend}")
    case = load_case(args.case, overrides=overrides)
    if args.restart:
        out = Path(args.restart)
        if args.output and Path(args.output).resolve() != out.resolve():
            raise InputError(f"--restart {out} continues the run in its own folder; "
                             f"-o {args.output} names another (drop -o, or copy the folder "
                             "and restart the copy)")
        if args.overwrite:
            raise InputError("--overwrite starts afresh and --restart continues: give one")
        if not out.is_dir():
            raise InputError(f"{out}: --restart expects an existing output folder")
    else:
        out = Path(args.output) if args.output else Path("results") / Path(args.case).stem
    _check_output_dir(out)
    result = run(case, out, progress=False if args.no_progress else None,
                 restart=bool(args.restart), checkpoint_every=args.checkpoint_every,
                 handle_signals=True, overwrite=args.overwrite)
    s = result.summary
    print(f"{s['status']}: {s['steps']} steps to t = {s['end_time']:.4e} s, {s['nodes']} nodes, "
          f"{s['wall_time_s']:.2f} s wall, "
          f"{(s['node_stage_updates_per_second'] or 0) / 1e6:.2f} M node-stage updates/s")
    print(f"results in {printable(out)}/ (history.csv, summary.json, fields.pvd)")
    if args.plot:
        from .plot import plot_results
        written = plot_results(out)
        print(f"pictures in {printable(out / 'plots')}/ ({', '.join(p.name for p in written)})")
    return 0


def _check_output_dir(out: Path):
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{out}: cannot create output folder ({exc.strerror})") from None


def _check(args) -> int:
    from .case import load_case
    from .checks import check_case

    case = load_case(args.case, overrides=args.overrides)
    report, problems = check_case(case)
    print("\n".join(printable(line) for line in report.splitlines()))
    if args.ranks and case.run.method != "fv":
        print(f"partition: run.method = {case.run.method!r} runs on one rank (only the FV "
              "scheme runs on several)")
    elif args.ranks:
        from .parallel.partition import partition_report
        from .scheme.discretisation import discretise
        print("\n".join(partition_report(discretise(case), args.ranks)))
    if problems:
        # what run would refuse is an input error here too
        raise InputError(f"{case.source}: {problems[0]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
