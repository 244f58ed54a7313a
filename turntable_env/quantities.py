"""A uniform record for printing parameters: value, unit, given or derived, and source.

Every parameter dataclass offers ``describe()`` returning a list of
:class:`Quantity`; ``turntable params --json`` prints them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

__all__ = ["Quantity"]


@dataclass(frozen=True)
class Quantity:
    """One printed parameter.

    Attributes:
        name: machine-readable key (e.g. ``"tube.K_x"``).
        value: number or list of numbers, SI units.
        unit: SI unit string.
        kind: ``"given"`` (typed from the thesis or a stated source) or ``"derived"``
            (computed by the formula in ``source``).
        source: thesis table/equation or the reasoning for the value.
    """

    name: str
    value: float | list[float] | str | bool
    unit: str
    kind: Literal["given", "derived"]
    source: str

    def to_dict(self) -> dict:
        return {"value": self.value, "unit": self.unit, "kind": self.kind, "source": self.source}
