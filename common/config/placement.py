"""Placement: the nodes a scenario's services run on, and the medium that joins each node pair.

Without a ``[placement]`` table every link uses the network profile (``[network]``), as it
always has. With one, the vehicle node ``auv`` moves with the AUV and each *station* is a
fixed node (a buoy, a ship, a shore station) at a position; each service runs on one node
(``auv`` unless ``services`` says otherwise). A link between two services on one node is
local: ideal, no modelled fault. A link between the vehicle and a station uses the station's
medium: ``"acoustic"`` (common/netmodel/acoustic_link.py, with ``[placement.acoustic]``) or
``"generic"`` (the ``[network]`` profile of the link, as without placement). Two stations
talk over the generic profile (a radio or cable link at the surface).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Literal

from common.config.acoustic import AcousticMedium
from common.config.errors import ConfigValueError

VEHICLE_NODE = "auv"  # the node that moves with the vehicle
MediumKind = Literal["local", "generic", "acoustic"]
_NODE_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")


@dataclass(frozen=True, kw_only=True)
class Station:
    """A fixed node: its name, position (world frame, metres) and medium to the vehicle."""

    name: str
    x_m: float
    y_m: float
    medium: Literal["acoustic", "generic"] = "acoustic"

    def __post_init__(self) -> None:
        if _NODE_RE.match(self.name) is None or self.name == VEHICLE_NODE:
            raise ConfigValueError(
                "name",
                f"{self.name!r} is not a valid station name, expected letters, digits, "
                f"'_', '.', '-' and not {VEHICLE_NODE!r} (the vehicle's node)",
            )
        for key in ("x_m", "y_m"):
            if not math.isfinite(getattr(self, key)):
                raise ConfigValueError(key, f"{getattr(self, key)!r} is not a finite number")


@dataclass(frozen=True, kw_only=True)
class PlacementConfig:
    """Where each service runs and which medium joins the nodes (see the module docstring)."""

    stations: tuple[Station, ...] = ()
    # service name -> node name ("auv" or a station); services not named run on "auv"
    services: dict[str, str] = field(default_factory=dict)
    acoustic: AcousticMedium = field(default_factory=AcousticMedium)
    # the water around the area, metres beyond world.area on every side: a station must lie
    # in it (a ship 3 km off a 100 m survey box is in the water; one 50 km away is a typo)
    water_margin_m: float = 10_000.0

    def __post_init__(self) -> None:
        names = [s.name for s in self.stations]
        for i, n in enumerate(names):
            if n in names[:i]:
                raise ConfigValueError(
                    ("stations", i, "name"), f"{n!r} is declared twice, expected each once"
                )
        known = (VEHICLE_NODE, *names)
        for service, node in self.services.items():
            if node not in known:
                raise ConfigValueError(
                    ("services", service),
                    f"{node!r} is an unknown node, expected one of {', '.join(map(repr, known))}",
                )
        if not (math.isfinite(self.water_margin_m) and self.water_margin_m >= 0.0):
            raise ConfigValueError(
                "water_margin_m", f"{self.water_margin_m!r} is invalid, expected >= 0"
            )

    @property
    def declared(self) -> bool:
        """Whether the scenario places anything (else every link is generic, as always)."""
        return bool(self.stations or self.services)

    def node_of(self, service: str) -> str:
        """The node a service runs on."""
        return self.services.get(service, VEHICLE_NODE)

    def station(self, name: str) -> Station:
        """The station of that name (KeyError if there is none)."""
        for s in self.stations:
            if s.name == name:
                return s
        raise KeyError(name)

    def medium(self, a: str, b: str) -> MediumKind:
        """The medium joining nodes a and b."""
        if not self.declared:
            return "generic"
        if a == b:
            return "local"
        if VEHICLE_NODE in (a, b):
            return self.station(b if a == VEHICLE_NODE else a).medium
        return "generic"

    def link_medium(self, source: str, receiver: str) -> MediumKind:
        """The medium a link from service `source` to service `receiver` crosses."""
        return self.medium(self.node_of(source), self.node_of(receiver))
