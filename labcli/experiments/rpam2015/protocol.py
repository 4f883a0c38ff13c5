"""The rPAM protocol kind, ``rpam``, as plain data for the loader.

An rPAM protocol (``protocols/rpam2015.toml``) holds the joint, its actuators and their
materials, the stretch correction, the grids of its two experiments, the optimiser's
settings and the ``[sensors]`` table of its DAQ.  The loader checks the core's sections
(``[acquisition]``, ``[settling]``, ...) and keeps every other table as written
(``Protocol.sections``); the model (:mod:`labcli.experiments.rpam2015.models.rpam`)
checks its own keys, with its own sentences, when it reads them.

One protocol, two experiments: ``--experiment stretch`` records a run of kind
``rpam-stretch``, ``--experiment joint`` one of kind ``rpam-joint``.
"""

from __future__ import annotations

from ...core.experiment import ProtocolKind
from ...core.protocol import OPEN

EXPERIMENTS: dict[str, str] = {"stretch": "rpam-stretch", "joint": "rpam-joint"}

KINDS: dict[str, ProtocolKind] = {
    "rpam": ProtocolKind(
        name="rpam",
        sections={
            "device": ("optional", "device"),
            "acquisition": ("optional", "acquisition"),
            "rig": ("optional", OPEN),
            "channels": ("optional", "channel-map"),
            "settling": ("optional", "settling"),
        },
        extra_sections=True,
        experiments=EXPERIMENTS,
        described_as="an rPAM protocol",
    ),
}
