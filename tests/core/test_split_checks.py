"""A split's ids checked whole-array refuse what the id-by-id checks refuse, naming the same trial."""

from __future__ import annotations

import numpy as np
import pytest

from labcli.core.store.split import _checked_one_by_one, checked
from labcli.errors import StoreError


def outcome(check, *args):
    try:
        return check(*args)
    except StoreError as e:
        return str(e)


@pytest.mark.parametrize("seed", range(40))
def test_whole_array_checks_name_what_the_id_by_id_checks_name(seed):
    rng = np.random.default_rng(seed)
    complete = [int(i) for i in rng.permutation(60)[: int(rng.integers(20, 60))]]
    pool = complete + [int(i) for i in rng.integers(60, 70, size=int(rng.integers(0, 3)))]  # some not complete
    fit = [int(i) for i in rng.choice(pool, size=int(rng.integers(1, 15)), replace=bool(rng.random() < 0.3))]
    val = [int(i) for i in rng.choice(pool, size=int(rng.integers(0, 8)), replace=bool(rng.random() < 0.3))]
    if rng.random() < 0.6:  # most draws without overlap, so the later checks are reached
        val = [i for i in val if i not in set(fit)]
    got = outcome(checked, "run.h5", complete, fit, val)
    assert got == outcome(_checked_one_by_one, "run.h5", complete, list(fit), list(val))


def test_an_id_past_int64_is_named_as_no_complete_trial():
    with pytest.raises(StoreError, match=rf"^trial {10**30} is not a complete trial in r.h5"):
        checked("r.h5", [1, 2, 3], [1, 10**30], [2])
