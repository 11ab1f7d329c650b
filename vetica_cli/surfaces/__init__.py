"""Registry of surface models (:mod:`.base` states the convention each follows).

``MODELS`` maps ``surface.model`` values to model instances; :func:`get` looks
one up.  Each model module registers itself on import: adding a model is adding
its module and one import line below.
"""

from . import (
    sls,  # noqa: F401  (registers "sls")
    wiechert,  # noqa: F401  (registers "wiechert")
)
from . import hertz  # noqa: F401, I001  (registers "hertz"; after the others: the registry keeps their order)
from . import kelvin_voigt  # noqa: F401, I001  (registers "kelvin-voigt")
from .base import COMMON_KEYS, DEFAULT_MODEL, MODELS, CommonKey, DerivedKey, Quantity, SurfaceModel, get, register

__all__ = [
    "COMMON_KEYS",
    "DEFAULT_MODEL",
    "MODELS",
    "CommonKey",
    "DerivedKey",
    "Quantity",
    "SurfaceModel",
    "get",
    "register",
]
