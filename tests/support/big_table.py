"""A trial table far larger than the sample run: its 108 trials repeated under new trial numbers."""

from __future__ import annotations

from pathlib import Path

SAMPLE = Path(__file__).resolve().parents[2] / "sample_runs" / "trials.csv"


def big_table(path: Path, copies: int = 300) -> int:
    """Write ``copies`` copies of the sample run's trials to ``path`` (trials 1..n); returns n."""
    lines = SAMPLE.read_text().splitlines()
    rows = [lines[0]]
    for n, cells in enumerate((r.split(",") for _ in range(copies) for r in lines[1:]), start=1):
        rows.append(",".join([str(n), *cells[1:]]))
    path.write_text("\n".join(rows) + "\n")
    return len(rows) - 1
