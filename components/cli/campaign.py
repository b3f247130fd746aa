"""``calbench campaign CAMPAIGN.toml --out DIR [--workers N] [--scheduler ADDR] [--resume]
[--timeout S]``: run the cases that are missing, then write the reports. Exit 0 when the
campaign is complete and as its [expected] block says (without one: every case passed), 1 when
not, 2 on a bad file, 130 when interrupted (finished cases are kept: run again with --resume)."""
from __future__ import annotations

import argparse
import sys


def _cmd_campaign(args: argparse.Namespace) -> int:
    from components.campaign.execute import run_campaign
    from components.campaign.reader import load_campaign
    from components.campaign.reports import write_reports
    from components.errors import CampaignError, UserError

    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers {args.workers}: expected at least 1")
    if args.timeout is not None and not args.timeout > 0:
        raise UserError(f"--timeout {args.timeout}: expected a positive number of seconds")
    try:
        camp = load_campaign(args.campaign)
        print(f"campaign {camp.name}: {len(camp.cases)} cases ({len(camp.procedures)} procedure(s) x "
              f"{len(camp.systems)} system(s) x {len(camp.cases) // max(1, len(camp.procedures) * len(camp.systems) * camp.replicates)}"
              f" grid point(s) x {camp.replicates} seed(s)) -> {args.out}", flush=True)
        try:
            session = run_campaign(camp, args.out, workers=args.workers or 2, scheduler=args.scheduler,
                                   resume=args.resume, timeout=args.timeout, stream=sys.stderr)
        except KeyboardInterrupt:
            print(f"campaign {camp.name}: interrupted; finished cases are kept in {args.out}/cases "
                  "(run again with --resume)", file=sys.stderr)
            return 130
        summary = write_reports(camp, args.out, pages=args.pages, stream=sys.stderr)
    except CampaignError as e:
        raise UserError(str(e)) from None
    c = summary["counts"]
    from components.cli import json_option

    json_option.record(args, campaign=camp.name, counts=c, complete=summary["complete"],
                       all_passed=summary["all_passed"], expected=summary["expected"],
                       cases=[{k: row.get(k) for k in ("id", "verdict", "reason")} for row in summary["cases"]],
                       out=str(args.out))
    print(f"campaign {camp.name}: ran {len(session['ran'])} case(s) now; {c['pass']} passed, {c['fail']} failed, "
          f"{c['error']} errored, {c['missing']} missing of {c['total']} -> {args.out}/report.html, junit.xml, "
          "summary.json")
    for row in summary["cases"]:
        if row["verdict"] in ("fail", "error"):
            print(f"  {row['verdict']:5s} {row['id']}: {row['reason']}")
    if summary["expected"] is not None:
        ok = summary["expected"]["ok"]
        print(f"regression: {'as expected' if ok else 'NOT as expected: ' + ', '.join(summary['expected']['mismatches'])}")
        return 0 if ok and summary["complete"] else 1
    return 0 if summary["all_passed"] else 1


def register(sub) -> None:
    p = sub.add_parser("campaign", help="run a test campaign (procedures x systems x variations x seeds, judged "
                                        "against acceptance criteria) on Dask; JUnit/JSON/HTML reports")
    p.add_argument("campaign", help="campaign file (.toml)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (case records, reports, manifest)")
    p.add_argument("--workers", type=int, metavar="N", help="worker processes of the local cluster (default 2)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="use the Dask cluster at this scheduler address instead "
                                                          "(e.g. tcp://host:8786)")
    p.add_argument("--resume", action="store_true", help="run only the cases without a record in --out")
    p.add_argument("--timeout", type=float, metavar="S", help="per-case timeout [s] (default: the file's)")
    p.add_argument("--pages", type=int, default=3, metavar="N",
                   help="compare/diagnose pages of the N worst cases (default 3)")
    p.set_defaults(func=_cmd_campaign)
