"""``gmdh-thermal``: the learned IMU bias-versus-temperature model as a bridging method.

Like ``gmdh-airspeed`` it corrects neither the output nor the INS through the bridging hooks
(they are :class:`~fusion.bridging.interface.NoBridge`'s): it hands the filter a
:class:`~fusion.thermal.bias_model.ThermalBiasModel`, which the filter trains on its own bias
estimate while GNSS is good and whose predicted change it feeds into the bias estimate during
an outage (:mod:`fusion.thermal.link`). Its status reports the state, the training pairs, the
refits, the selected polynomial of each axis, and which axes the gate lets through.
"""

from __future__ import annotations

from fusion.bridging.interface import BridgeStatus, NoBridge
from fusion.config import BridgeConfig
from fusion.thermal.bias_model import AXES, ThermalBiasModel


class ThermalModelBridge(NoBridge):
    """The ``gmdh-thermal`` strategy (module docstring)."""

    name = "gmdh-thermal"

    def __init__(self, config: BridgeConfig | None = None) -> None:
        self.thermal_model = ThermalBiasModel(config)

    @property
    def status(self) -> BridgeStatus:
        """The learned model's state, pairs, refits, polynomials and the axes on."""
        model = self.thermal_model
        assert model is not None
        st = model.status
        on = ",".join(a for a, o in zip(AXES, st.on_axes, strict=True) if o) or "none"
        text = st.polynomial
        if st.state == "trained":
            text = (f"on: {on}; trained {st.t_min_k - 273.15:.1f}..{st.t_max_k - 273.15:.1f}"
                    f" degC; {text}")  # fmt: skip
        return BridgeStatus(self.name, st.state, samples=st.samples, refits=st.refits,
                            active=st.active, model=text,
                            fallback=tuple(not o for o in st.on_axes))  # type: ignore[arg-type]
