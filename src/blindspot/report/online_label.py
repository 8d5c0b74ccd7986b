"""How the report names a setting of the online ellipses: the ETH/UCY page's choice per fold
and the walks table's per predictor read the same label."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["online_setting_label"]


def online_setting_label(setting: Mapping[str, Any] | None) -> str:
    """An online-ellipses setting as the metrics files record it (``online_method`` and its
    ``online_<parameter>`` keys) in a table cell: "ACI gamma / window / rescale after"
    (``aci_window``, or no method but a gamma) or "scale eta / kappa" (``scale_tracker``); "-"
    for anything else."""
    if not isinstance(setting, Mapping):
        return "-"
    if setting.get("online_method") == "scale_tracker":
        return f"scale {setting['online_eta']:g} / {setting['online_kappa']:g}"
    if "online_gamma" in setting:
        return (f"ACI {setting['online_gamma']:g} / {setting['online_window']} / "
                f"{setting['online_rescale_after']}")
    return "-"
