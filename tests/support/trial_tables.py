"""A small trial table the command tests start from."""

from __future__ import annotations

from pathlib import Path


def write_small_trial_table(path: Path) -> Path:
    """Trials from the paper's own equations, 12 fit and 4 validation (ids 1-16), as a trial CSV at ``path``."""
    import pandas as pd

    from labcli.papers.takuma2014.models.synthetic import paper_trials
    from labcli.papers.takuma2014.tables import write_trial_csv

    table = pd.concat(
        [paper_trials(12, seed=1), paper_trials(4, seed=2, set_name="validation", start_id=13)], ignore_index=True
    )
    write_trial_csv(table, path)
    return path
