"""``gmdh-airspeed``, ``gmdh-wind`` and ``gmdh-pitot``: learned models of the air-data channel
as bridging methods.

It corrects neither the output nor the INS directly (its hooks are :class:`NoBridge`'s): it
hands the filter an :class:`~fusion.airspeed_model.OnlineAirspeedModel` (a GMDH network with
the regressor defaults of :class:`fusion.gmdh.GmdhRegressor`) which the air-data aiding
trains while the airspeed is known and fuses, with its own held-out error as the sigma,
when GNSS is lost and no pitot is usable (:mod:`fusion.aiding.airspeed`). Its status reports
what it learned: the state (``no inputs`` when the stream carries no controls or rpm), the
training pairs, the refits, the held-out error and the selected polynomial.

``gmdh-wind`` (:class:`WindModelBridge`) is the same arrangement for the wind profile: it hands
the filter an :class:`~fusion.wind_model.OnlineWindModel`, which the air-data aiding trains on
its mean-wind estimate against height while GNSS is good and fuses as a mean-wind measurement
when GNSS is lost (:mod:`fusion.aiding.airspeed`).

``gmdh-pitot`` (:class:`PitotErrorBridge`) hands the filter an
:class:`~fusion.pitot_model.OnlinePitotErrorModel`: the air-data aiding trains it on the
measured airspeed's error against the angle of attack, the sideslip and the airspeed while
GNSS is good, and with GNSS lost removes the learned error's change from the window's mean
from each measured airspeed before fusing it (behind its skill gate, inside its trained
range). Its status is ``active`` while the last airspeed was corrected.
"""

from __future__ import annotations

from fusion.airspeed_model import AirspeedModelStatus, OnlineAirspeedModel
from fusion.bridging.interface import BridgeStatus, NoBridge
from fusion.gmdh import GmdhRegressor
from fusion.pitot_model import OnlinePitotErrorModel
from fusion.wind_model import OnlineWindModel


def _describe(model: object) -> str:
    return model.polynomial(4) if isinstance(model, GmdhRegressor) else ""


class AirspeedModelBridge(NoBridge):
    """The ``gmdh-airspeed`` strategy (module docstring)."""

    name = "gmdh-airspeed"

    def __init__(self) -> None:
        self.airspeed_model = OnlineAirspeedModel(
            GmdhRegressor, method=self.name, describe=_describe
        )

    @property
    def status(self) -> BridgeStatus:
        """The learned model's state, pairs, refits, held-out error and polynomial."""
        model = self.airspeed_model
        assert model is not None
        return _status(self.name, model.status)


class WindModelBridge(NoBridge):
    """The ``gmdh-wind`` strategy (module docstring)."""

    name = "gmdh-wind"

    def __init__(self) -> None:
        self.wind_model = OnlineWindModel(GmdhRegressor, method=self.name, describe=_describe)

    @property
    def status(self) -> BridgeStatus:
        """The learned profile's state, pairs, refits, held-out error and polynomials."""
        model = self.wind_model
        assert model is not None
        return _status(self.name, model.status)


class PitotErrorBridge(NoBridge):
    """The ``gmdh-pitot`` strategy (module docstring)."""

    name = "gmdh-pitot"

    def __init__(self) -> None:
        self.pitot_model = OnlinePitotErrorModel(
            GmdhRegressor, method=self.name, describe=_describe
        )

    @property
    def status(self) -> BridgeStatus:
        """The learned error's state, pairs, refits, held-out error, polynomial, and whether
        the last measured airspeed was corrected."""
        model = self.pitot_model
        assert model is not None
        st = _status(self.name, model.status)
        return BridgeStatus(st.method, st.state, samples=st.samples, refits=st.refits,
                            model=st.model, model_rmse=st.model_rmse,
                            active=model.active)  # fmt: skip


def _status(name: str, st: AirspeedModelStatus) -> BridgeStatus:
    return BridgeStatus(name, st.state, samples=st.samples, refits=st.refits,
                        model=st.polynomial, model_rmse=st.validation_rmse_mps)  # fmt: skip
