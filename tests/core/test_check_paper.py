"""labcli.testing.check_paper: the self-test a paper plug-in runs (scikit-learn's check_estimator).

Both shipped papers and the toy paper of the tests pass it; papers broken in one promise each
fail it with a sentence naming the paper and the promise.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from support import toy

from labcli.papers import rpam2015, takuma2014
from labcli.testing import PaperCheckError, check_paper


@pytest.mark.parametrize("paper", [takuma2014, rpam2015.PAPER, toy.ToyPaper()], ids=["takuma2014", "rpam2015", "toy"])
def test_the_shipped_papers_and_the_toy_pass(paper):
    check_paper(paper)  # raises PaperCheckError naming what is wrong


class _Broken(toy.ToyPaper):
    """The toy paper with one promise broken by a subclass."""


def _broken(**changes):
    return type("Broken", (_Broken,), changes)()


class _FrozenRig(toy.ToyRig):
    def samples(self, n, rate_hz):
        t, counts = super().samples(n, rate_hz)
        return t[::-1].copy(), counts  # times that run backwards


class _NoisyRig(toy.ToyRig):
    draws = iter(range(1000))

    def samples(self, n, rate_hz):
        t, counts = super().samples(n, rate_hz)
        return t, counts + next(self.draws)  # another answer every time for the same seed


def _rig(cls):
    def make_rig(self, mode, *, seed=0, noise=1.0, drift=None, tau_s=0.7, options=None):
        return cls(seed=seed, noise=noise)

    return make_rig


def _records(**changes):
    def record_type(self, run_kind):
        base = toy.ToyPaper().record_type(run_kind)
        return type("R", (type(base),), changes)()

    return record_type


@pytest.mark.parametrize(
    "paper, message",
    [
        (
            _broken(default_protocols={"fit": "nowhere"}),
            "default of labcli fit with 'nowhere', a protocol it does not ship",
        ),
        (_broken(default_sim_mode="other"), "default_sim_mode 'other' is not one of its sim_modes"),
        (_broken(untagged_run_kind="force"), "untagged_run_kind 'force' is not one of its run kinds"),
        (_broken(run_kinds=()), "declares no run kind"),
        (_broken(analysis_options={"fit": dict}), "options of labcli fit must be a dataclass"),
        (_broken(analysis_options={"validate": toy.ToyFitOptions}), "gives no analysis for it"),
        (_broken(sensing_options=dict), "options of labcli sense must be a dataclass"),
        (_broken(record_type=_records(kind="other")), "the record type of 'toy' says its kind is 'other'"),
        (_broken(record_type=_records(noun=3)), "has no noun of the right type"),
        (_broken(make_rig=_rig(_FrozenRig)), "the times of its toy rig's frames do not increase"),
        (_broken(make_rig=_rig(_NoisyRig)), "its toy rig gives other frames for the same seed"),
    ],
    ids=lambda v: v if isinstance(v, str) and len(v) < 30 else None,
)
def test_a_broken_promise_is_named_in_one_sentence(paper, message):
    with pytest.raises(PaperCheckError, match="^paper 'toy': ") as e:
        check_paper(paper)
    assert message in str(e.value)


def test_a_paper_lacking_members_is_told_which():
    @dataclasses.dataclass
    class Bare:
        name: str = "bare"

    with pytest.raises(
        PaperCheckError, match="^paper 'bare': lacks .*analysis.*run_kinds.* of labcli.core.paper.Paper"
    ):
        check_paper(Bare())


def test_the_rig_check_really_samples(monkeypatch):
    seen = []
    real = toy.ToyRig.samples

    def spy(self, n, rate_hz):
        seen.append((n, rate_hz))
        return real(self, n, rate_hz)

    monkeypatch.setattr(toy.ToyRig, "samples", spy)
    check_paper(toy.ToyPaper())
    assert seen and all(n > 1 and rate > 0 for n, rate in seen)
    assert np.isfinite(seen[0][1])
