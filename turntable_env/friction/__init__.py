"""Friction library (§2.2): static and dynamic models behind one state-space interface.

Modules: :mod:`.kernels` (compiled force/rates/update for every model),
:mod:`.models` (immutable parameter objects, test rigs, §4.2.1 GMS rules),
:mod:`.gms2d` (GMS in the contact plane, §3.3.2).
"""

from .models import (
    GMS,
    Breedveld,
    Classical,
    Dahl,
    ElastoPlastic,
    FrictionModel,
    FrictionResponse,
    FrictionState,
    Karnopp,
    Leuven,
    LuGre,
    StribeckCurve,
    StribeckParams,
)

__all__ = [
    "GMS",
    "Breedveld",
    "Classical",
    "Dahl",
    "ElastoPlastic",
    "FrictionModel",
    "FrictionResponse",
    "FrictionState",
    "Karnopp",
    "Leuven",
    "LuGre",
    "StribeckCurve",
    "StribeckParams",
]
