"""`nuparquet validate DATAROOT --version V`: every integrity problem, without converting."""

from __future__ import annotations

from dataclasses import fields

from nuparquet.cli.arguments import add_options
from nuparquet.conversion.options import ConvertOptions


def register(sub) -> None:
    p = sub.add_parser(
        "validate",
        help="check a nuScenes-layout dataroot for integrity problems (nothing is written)",
        description="Check that every table exists and is a JSON array of records, required fields have the "
        "right JSON types, tokens are unique, every foreign key and prev/next resolves, nbr_samples / "
        "nbr_annotations agree and quaternions are finite unit quaternions. Problems are listed all at "
        "once (file, record index, token). Exit 0 when clean, 1 when problems were found, 2 for usage errors.",
    )
    p.add_argument("dataroot", help="dataset root holding the version folder")
    p.add_argument("--version", required=True, help="version folder name, e.g. v1.0-mini")
    add_options(p, ConvertOptions, skip=tuple(f.name for f in fields(ConvertOptions) if f.name != "allow_dangling"))
    p.add_argument("--max-problems", type=int, default=50, help="problems to print (the rest are counted)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.cli.progress import bars
    from nuparquet.conversion import validate
    from nuparquet.problems import count_problems, format_problems
    from nuparquet.sources.dangling import Finding

    result = validate(args.dataroot, args.version, on_progress=bars(not args.quiet),
                      allow_dangling=args.allow_dangling)
    if result.warnings:
        print(format_problems(result.warnings, limit=args.max_problems))
    if result.problems:
        print(format_problems(result.problems, limit=args.max_problems))
        n = count_problems(result.problems)
        print(f"{n} problem{'s' if n != 1 else ''} found")
        return 1
    accepted = count_problems([w for w in result.warnings if isinstance(w, Finding)])
    print(f"ok: {len(result.records)} tables, {sum(result.records.values()):,} records, no problems"
          + (f" ({accepted:,} dangling references and count mismatches accepted: --allow-dangling)" if accepted else ""))
    return 0
