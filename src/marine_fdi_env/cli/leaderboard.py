"""``marine-fdi leaderboard``: the leaderboard's table from its entries (docs/submitting.md)."""

from __future__ import annotations

from pathlib import Path

from .failures import fail

__all__ = ["leaderboard_main"]


def leaderboard_main(argv=None) -> int:
    from .common import CommandParser, parse_cli

    ap = CommandParser(
        prog="marine-fdi leaderboard",
        description="Build the leaderboard's table from entry folders (marine-fdi submit): per agent, its training "
        "seeds pooled, the normalised score of every suite, their interquartile mean and the probability of "
        "improvement over reference, each with its 95 %% interval, and the DX 2025 metrics; written between the "
        "markers of --out.  Run from the repository's root.",
    )
    ap.add_argument(
        "--entries",
        nargs="+",
        type=Path,
        default=[Path("leaderboard") / "entries"],
        metavar="DIR",
        help="entry folders or folders of entries (default leaderboard/entries)",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=Path("leaderboard") / "README.md",
        metavar="FILE.md",
        help="the Markdown file whose leaderboard block is written (default leaderboard/README.md)",
    )
    ap.add_argument(
        "--check",
        action="store_true",
        help="write nothing; fail (exit 2) when --out's table is not the one the entries give (stale)",
    )
    ap.add_argument(
        "--hashes-only",
        action="store_true",
        help="with --check: compare the table's fingerprints (the sha256 of the entries' files and of the table's "
        "text) instead of building the table again: a second instead of half a minute",
    )
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    try:
        from ..benchmark.leaderboard import (
            BEGIN,
            END,
            find_entries,
            fingerprint_problem,
            leaderboard_block,
            write_block,
        )
        from ..errors import DataFileError, UsageError
        from ..outputs import check_suffix, prepare_out

        check_suffix(args.out, "--out", (".md",), "the leaderboard page")
        if args.hashes_only and not args.check:
            raise UsageError("--hashes-only goes with --check")
        dirs = find_entries(args.entries)
        if args.check and args.hashes_only:
            text = args.out.read_text(encoding="utf-8") if args.out.is_file() else ""
            problem = fingerprint_problem(text, dirs)
            if problem:
                raise DataFileError(f"{args.out}: {problem}")
            print(f"{args.out}: the table's fingerprints match its {len(dirs)} entries")
            return 0
        block = leaderboard_block(dirs, shown_root=args.out.parent)
        if args.check:
            text = args.out.read_text(encoding="utf-8") if args.out.is_file() else ""
            if BEGIN not in text or END not in text or text[text.index(BEGIN) : text.index(END) + len(END)] != block:
                raise DataFileError(
                    f"{args.out}: the leaderboard table is stale (not the one its {len(dirs)} entries give); "
                    "rerun marine-fdi leaderboard and commit it"
                )
            print(f"{args.out}: the table is the one its {len(dirs)} entries give")
            return 0
        prepare_out(args.out, "--out", is_dir=False)
        changed = write_block(args.out, block)
    except ValueError as e:
        return fail("marine-fdi leaderboard", e)
    print(f"{'wrote' if changed else 'unchanged:'} the table of {args.out} ({len(dirs)} entries)")
    return 0
