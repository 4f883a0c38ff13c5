"""Bad-input cases of ``labcli sense``: a model of another paper or rig, a rig whose channels differ
from the model's, a publish address of the wrong form, a run file that exists.

Each is refused before the stream starts, so no file changes.  What happens once it runs (a TCP
port in use, a client that leaves, a rig that stalls or is unplugged, with ``--record``) is
tested in tests/cli/test_sense_cli.py, tests/cli/test_sense_record.py and
tests/sensing/test_sensing_live.py.
"""

from __future__ import annotations

from pathlib import Path

from support.bad_input import SIM, Case

ORDER = 60

SENSE = ["sense", "--port", SIM, "--seconds", "1", "--jsonl", "--model", "run.model.json"]
STRETCH = Path(__file__).resolve().parents[3] / "sample_runs" / "stretch.model.json"

CASES: list[Case] = [
    Case(
        "sense-model-other-paper",
        "model JSON",
        "model of another paper (the rPAM stretch test's, sense)",
        ["sense", "--port", SIM, "--seconds", "1", "--jsonl", "--model", "stretch.model.json"],
        [
            "The model file stretch.model.json is not a model any installed paper can estimate with; "
            "pass the .json file `labcli fit` wrote."
        ],
        files={"stretch.model.json": lambda world: STRETCH.read_bytes()},
    ),
    Case(
        "sense-model-other-rig",
        "model JSON",
        "model of another rig's protocol (sense --protocol rpam2015)",
        [*SENSE, "--protocol", "rpam2015"],
        [
            "The model was fitted on the rig of protocol takuma2014, and rpam2015 describes another rig (its "
            "calibration or geometry differ); fit a model on this rig, or use a protocol of the model's rig."
        ],
    ),
    Case(
        "sense-channels-differ",
        "port",
        "a rig whose channels differ from the model's (sense on the rPAM stand)",
        ["sense", "--port", "sim://?mode=rpam&clock=virtual", "--seconds", "1", "--jsonl", "--model", "run.model.json"],
        [
            "The rig sends the channels P_A,P_B,POT,LEN but the model reads P_L1,P_R1,P_L2,P_R2,POT1,POT2 too; "
            "connect the rig the model was fitted on, or fit a model for this one."
        ],
    ),
    Case(
        "sense-publish-form",
        "CLI argument",
        "publish address without a port (sense)",
        [*SENSE, "--publish", "tcp://127.0.0.1"],
        [
            "Cannot publish on 'tcp://127.0.0.1': expected tcp://HOST:PORT, e.g. tcp://127.0.0.1:5555 "
            "(tcp://0.0.0.0:5555 for every interface)."
        ],
    ),
    Case(
        "sense-record-exists",
        "output path",
        "--record onto an existing run file (sense)",
        [*SENSE, "--record", "acq.h5"],
        ["acq.h5 already exists; choose a new file name for the session's run file."],
    ),
]
