"""Where a fitted model's data came from, and whether a later run came from the same rig.

A model remembers the identity of the run it was fitted on (:func:`run_identity`): the
data (the run's uid, or its start time and source when the file has no uid), the rig
(the device's ID reply, its calibration, and for the simulated rig its seed: each seed is
another rig) and the protocol.  :func:`rig_differences` names what differs between that
identity and the identity of a run the model is applied to; :func:`same_data` says whether
two identities describe the same recorded trials (a copy of a run is the same data).

The run file is read through its public API only: ``attrs``, ``calibration()``,
``protocol_text`` and, where the store offers it, ``rig_identity()``.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit


def _sim_seed(port: str) -> int | None:
    """The seed of a ``sim://`` port (the simulated rig's identity); None for a real port."""
    if not port.startswith("sim://"):
        return None
    seeds = parse_qs(urlsplit(port).query).get("seed", ["0"])  # the simulator's default seed is 0
    try:
        return int(seeds[-1])
    except ValueError:
        return None


def _digest(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16] if text else ""


def run_identity(run: Any, path: str | Path) -> dict[str, Any]:
    """The identity of an open run file (plain data, JSON-ready)."""
    a = run.attrs
    cal = run.calibration() or {"gain": [], "offset": []}
    rig = {
        "device": a.get("device", ""),
        "firmware": a.get("firmware", ""),
        "port": a.get("port", ""),
        "calibration": {"gain": [float(x) for x in cal["gain"]], "offset": [float(x) for x in cal["offset"]]},
    }
    latest = run.sessions.rig_identity()
    if latest is not None:  # the rig of the run's latest session (a resumed run may have moved rigs)
        rig.update(device=latest.device, firmware=latest.firmware)
        if latest.gain:
            rig["calibration"] = {"gain": [float(x) for x in latest.gain], "offset": [float(x) for x in latest.offset]}
    uid = a.get("uid") or a.get("run_uid") or ""
    data = str(uid) or f"{a.get('started', '')}|{a.get('source', '')}|{a.get('port', '')}"
    return {
        "run": Path(path).name,
        "data": data,
        "device": str(rig.get("device") or ""),
        "firmware": str(rig.get("firmware") or ""),
        "sim_seed": _sim_seed(str(rig.get("port") or "")),
        "calibration": {k: [float(x) for x in v] for k, v in dict(rig.get("calibration") or {}).items()},
        "channels": [str(c) for c in getattr(run, "channels", ())],
        "protocol": str(a.get("protocol", "")),
        "protocol_sha256": _digest(run.protocol_text),
    }


def table_identity(path: str | Path, protocol: Any) -> dict[str, Any]:
    """The identity of a CSV table: its name and the protocol it is read with (no rig recorded)."""
    return {
        "run": Path(path).name,
        "data": f"table:{Path(path).name}",
        "device": "",
        "firmware": "",
        "sim_seed": None,
        "calibration": {},
        "channels": [],
        "protocol": str(getattr(protocol, "name", "")),
        "protocol_sha256": _digest(getattr(protocol, "text", "")),
    }


def same_data(a: Mapping[str, Any], b: Mapping[str, Any]) -> bool:
    """True when both identities name the same recorded trials."""
    return bool(a.get("data")) and a.get("data") == b.get("data")


def _calibration_differs(a: Mapping[str, Any], b: Mapping[str, Any]) -> bool:
    for key in ("gain", "offset"):
        x, y = a.get(key), b.get(key)
        if (
            x
            and y
            and (
                len(x) != len(y)
                or not all(math.isclose(p, q, rel_tol=1e-9, abs_tol=1e-12) for p, q in zip(x, y, strict=False))
            )
        ):
            return True
    return False


def rig_differences(fit: Mapping[str, Any], run: Mapping[str, Any], *, protocol_text: bool = True) -> list[str]:
    """What differs between the rig (and protocol) a model was fitted on and a run's; [] when nothing known does.

    Fields either side does not know (a table has no rig) are not compared.  With
    ``protocol_text`` the protocols' texts are compared too (validate: the same protocol;
    classify reads a push protocol, so only the rig is compared there).
    """
    out = []
    fdev = " ".join(x for x in (fit.get("device"), fit.get("firmware") and f"firmware {fit['firmware']}") if x)
    rdev = " ".join(x for x in (run.get("device"), run.get("firmware") and f"firmware {run['firmware']}") if x)
    if fdev and rdev and fdev != rdev:
        out.append(f"device {fdev}, here {rdev}")
    if fit.get("sim_seed") is not None and run.get("sim_seed") is not None and fit["sim_seed"] != run["sim_seed"]:
        out.append(f"simulated rig seed {fit['sim_seed']}, here seed {run['sim_seed']}")
    if _calibration_differs(fit.get("calibration") or {}, run.get("calibration") or {}):
        out.append("another channel calibration (gain or offset)")
    if (
        protocol_text
        and fit.get("protocol_sha256")
        and run.get("protocol_sha256")
        and fit["protocol_sha256"] != run["protocol_sha256"]
    ):
        out.append(f"protocol {fit.get('protocol') or '?'} with other settings than {run.get('protocol') or '?'} here")
    return out


def rig_warning(
    model_name: str,
    fit: Mapping[str, Any] | None,
    run_name: str,
    run: Mapping[str, Any],
    *,
    protocol_text: bool = True,
) -> str | None:
    """One sentence warning that a model is applied to a run from another rig or protocol, or None.

    A model that does not say what it was fitted on (``fit`` None) has nothing to compare.
    """
    if not fit:
        return None
    diffs = rig_differences(fit, run, protocol_text=protocol_text)
    if not diffs:
        return None
    return (
        f"{model_name} was fitted on {fit.get('run') or 'another run'} ({'; '.join(diffs)}): "
        f"its results on {run_name} may not hold; fit a model on a run of this rig."
    )
