"""``synptv claims``: the paper's claims against the truth, and the mutations they
catch (docs/claims.md)."""

import argparse
import json
import sys

from validation.commands.common import COUNT, SEED
from validation.workflow.progress import ProgressBar


def run_mutations(args: argparse.Namespace) -> int:
    from validation.mutations.report import kill_table
    from validation.mutations.runner import run_mutations

    control, outcomes = run_mutations(
        "full" if args.full else "quick",
        seed=args.seed,
        names=args.mutation or None,
        workers=args.workers,
        progress=_progress(args, "mutation"),
    )
    if control.failed:
        print(f"claims failing without any mutation: {', '.join(control.failed)}", file=sys.stderr)
    if args.json:
        json.dump([o.as_dict() for o in outcomes], sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        for line in kill_table(outcomes):
            print(line)
    return 0 if not control.failed and all(o.ok for o in outcomes) else 1


def _progress(args: argparse.Namespace, noun: str):
    def progress(done) -> None:
        if not args.quiet:
            what = done.name or f"control (no {noun})"
            print(
                f"{noun}s: {what} done in {done.seconds:.0f} s, {len(done.failed)} of "
                f"{len(done.checked)} claims failed",
                file=sys.stderr,
            )

    return progress


def run_audit(args: argparse.Namespace) -> int:
    from validation.audit import audit_table, run_audit

    rows = run_audit(
        "full" if args.full else "quick",
        seed=args.seed,
        workers=args.workers,
        progress=_progress(args, "perturbation"),
    )
    if args.json:
        records = [
            {
                "setting": r.audited.target,
                "perturbation": r.label,
                "outcome": r.verdict,
                "killed_by": list(r.killed_by),
                "effect": None if r.effect != r.effect else r.effect,
                "moved": r.moved,
                "reason": r.audited.reason,
            }
            for r in rows
        ]
        json.dump(records, sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        print(audit_table(rows))
    return 0


def run_claims(args: argparse.Namespace) -> int:
    from validation.claims import ClaimContext, run_claims

    if args.audit:
        return run_audit(args)
    if args.mutations or args.mutation:
        return run_mutations(args)
    ctx = ClaimContext("full" if args.full else "quick", seed=args.seed)
    bar = ProgressBar("claims", enabled=not args.quiet)
    results = run_claims(ctx, progress=bar)
    if args.json:
        json.dump([r.as_dict() for r in results], sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        for r in results:
            mark = "PASS" if r.passed else "FAIL"
            print(f"{mark}  {r.id:42s} {r.value:10.4g}   {r.tolerance}   [{r.source}]")
        failed = sum(not r.passed for r in results)
        print(f"{len(results) - failed} passed, {failed} failed")
    return 0 if all(r.passed for r in results) else 1


def add_claims_parser(sub) -> None:
    """The ``synptv claims`` subcommand."""
    claims = sub.add_parser(
        "claims",
        help="regress the paper's claims against truth; exit status 1 if one fails",
        description="Measure every regressable statement of the paper (docs/claims.md) "
        "against the simulator's truth and compare it with its tolerance.",
    )
    size = claims.add_mutually_exclusive_group()
    size.add_argument(
        "--quick",
        action="store_true",
        help="CI size (default; about a minute on an idle 2-core machine, minutes when loaded)",
    )
    size.add_argument("--full", action="store_true", help="the sizes the tolerances assume")
    claims.add_argument("--json", action="store_true", help="print a JSON list of claims")
    claims.add_argument("--seed", type=SEED, default=0)
    claims.add_argument("--quiet", action="store_true", help="no progress bar")
    claims.add_argument(
        "--mutations",
        action="store_true",
        help="break the code one named way at a time (docs/claims.md §5) and report which "
        "claims catch each; exit status 1 if one is not caught as expected",
    )
    claims.add_argument(
        "--mutation",
        action="append",
        metavar="NAME",
        help="run only this mutation (repeatable; implies --mutations)",
    )
    claims.add_argument(
        "--audit",
        action="store_true",
        help="perturb every setting and constant of the chain (docs/claims.md §6) and print "
        "the table of what each did to the claims",
    )
    claims.add_argument(
        "--workers",
        type=COUNT,
        default=2,
        help="mutations or perturbations run at once (default 2)",
    )
    claims.set_defaults(run=run_claims)
