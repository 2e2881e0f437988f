"""Bridging registry: every GNSS-outage bridging method by name, and its default inputs.

:func:`make_bridge` builds a strategy for :class:`fusion.filter.NavFilter` by name
(:data:`BRIDGE_METHODS`):

========================  =====================================================================
``none``                  plain filter (free-inertial coasting,
                          :class:`fusion.bridging.interface.NoBridge`)
``gmdh``                  P0: six GMDH networks, one per N/E/D position and velocity error
                          component; their prediction is subtracted from the filter's *output*
                          during an outage (the INS and the filter are left alone)
``gmdh-pseudo``           P3: the same networks give pseudo-GNSS position and velocity (the free
                          INS minus the predicted drift), fused by the filter's GNSS update
``mlp``                   P1: NARX MLP (35 tanh neurons, current and previous inputs plus its own
                          previous output, Levenberg-Marquardt), horizontal components only
``rbf``                   P0's comparator: 15 Gaussian neurons per component
``bp-parallel``           P2: one small sigmoid network per component; inputs the component
                          (since the outage start) and its rate
``gmdh-airspeed``         a learned vehicle model: GMDH learns true airspeed from the controls,
                          propeller rpm, air density, attitude and specific force while the
                          airspeed is known; with GNSS lost and no usable pitot the filter
                          fuses its prediction (:mod:`fusion.bridging.airspeed`)
``gmdh-wind``             a learned wind profile: GMDH learns the filter's mean wind against
                          height while GNSS is good; with GNSS lost the filter fuses its
                          prediction at the current height (:mod:`fusion.wind_model`)
``gmdh-pitot``            a learned pitot position error: GMDH learns the measured airspeed's
                          error against angle of attack, sideslip and airspeed while GNSS is
                          good; with GNSS lost the filter removes the predicted error from
                          the measured airspeed, behind a skill gate and inside the trained
                          range (:mod:`fusion.pitot_model`)
``gmdh-thermal``          a learned IMU bias against die temperature and its rate: GMDH learns
                          the filter's bias estimate while GNSS is good; with GNSS lost the
                          filter moves its bias by the predicted change
                          (:mod:`fusion.thermal.bias_model`)
========================  =====================================================================

What each method achieves on held-out flights is measured by ``bench/bridging.py`` and
reported in ``docs/results.md`` ("Bridging (GMDH and the learned methods)"); ``none`` is the
default.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fusion.bridging.airspeed import AirspeedModelBridge, PitotErrorBridge, WindModelBridge
from fusion.bridging.interface import Bridge, NoBridge
from fusion.bridging.learned import LearnedBridge
from fusion.bridging.models import ComponentModel, NarxModel, StatelessModel
from fusion.bridging.thermal import ThermalModelBridge
from fusion.choices import BRIDGE_METHODS
from fusion.config import BridgeConfig
from fusion.gmdh import GmdhRegressor
from fusion.regressors import BpNet, NarxMLP, RbfNet

GMDH_FEATURES: tuple[str, ...] = ("t", "t2", "sinpsi", "cospsi")
"""Default inputs of the GMDH, RBF and MLP networks: time into the outage, its square and the
heading (chosen with ``python bench/bridging.py --tune`` over 17 feature sets; the comparison
is in ``bench/results/bridging_tuning.json``)."""
P0_FEATURES: tuple[str, ...] = ("own",)
"""Paper P0's inputs: the component's own INS value."""
MLP_FEATURES: tuple[str, ...] = GMDH_FEATURES
"""P1's NARX MLP inputs: the same as GMDH's (azimuth and time; P1's NARX structure — current
and previous inputs plus its own previous output — is kept). Few inputs on purpose:
Levenberg-Marquardt costs O(samples x weights^2)."""
BP_FEATURES: tuple[str, ...] = ("own_rel", "own_rate")
"""P2's inputs: the component and its epoch-to-epoch difference (per second)."""

DEFAULT_FEATURES: dict[str, tuple[str, ...]] = {
    "gmdh": GMDH_FEATURES,
    "gmdh-pseudo": GMDH_FEATURES,
    "rbf": GMDH_FEATURES,
    "mlp": MLP_FEATURES,
    "bp-parallel": BP_FEATURES,
}

METHOD_DEFAULTS: dict[str, dict[str, Any]] = {
    "mlp": {"refit_period_s": 20.0},
    "bp-parallel": {"refit_period_s": 20.0, "max_samples": 1000},
}
"""Per-method changes to ``BridgeConfig()`` when :func:`make_bridge` gets no config: the slow
trainers (Levenberg-Marquardt, back-propagation) refit less often and on fewer pairs; each of
their refits is a bounded continuation of the previous one (``mlp_max_nfev``,
``bp_epochs``)."""


def make_bridge(name: str, config: BridgeConfig | None = None) -> Bridge:
    """Build the bridging strategy ``name`` (one of :data:`BRIDGE_METHODS`).

    Parameters
    ----------
    name : str
        ``none``, ``gmdh``, ``gmdh-pseudo``, ``mlp``, ``rbf``, ``bp-parallel``,
        ``gmdh-airspeed``, ``gmdh-wind``, ``gmdh-pitot`` or ``gmdh-thermal``.
    config : BridgeConfig, optional
        Training and model settings. Fields not set explicitly take the method's
        :data:`METHOD_DEFAULTS`, then ``BridgeConfig``'s defaults; ``features=None`` picks
        the method's default inputs (:data:`DEFAULT_FEATURES`).

    Returns
    -------
    Bridge
        A fresh strategy (give each :class:`~fusion.filter.NavFilter` its own).

    Raises
    ------
    ValueError
        For an unknown name (the message lists the methods).
    """
    if name not in BRIDGE_METHODS:
        raise ValueError(
            f"unknown bridging method {name!r}; valid methods: {', '.join(BRIDGE_METHODS)}"
        )
    if name == "none":
        return NoBridge()
    if name == "gmdh-airspeed":
        return AirspeedModelBridge()
    if name == "gmdh-wind":
        return WindModelBridge()
    if name == "gmdh-pitot":
        return PitotErrorBridge()
    if name == "gmdh-thermal":
        return ThermalModelBridge(config)
    # the method's defaults fill in whatever the caller did not set explicitly
    given = {} if config is None else config.model_dump(include=config.model_fields_set)
    cfg = BridgeConfig(**{**METHOD_DEFAULTS.get(name, {}), **given})
    features = cfg.features if cfg.features is not None else DEFAULT_FEATURES[name]
    factory: Callable[[], ComponentModel]
    components: tuple[int, ...] = (0, 1, 2, 3, 4, 5)
    budget = None
    if name in ("gmdh", "gmdh-pseudo"):

        def factory() -> ComponentModel:
            # P0's network (the papers' comparison), not the regressor defaults
            return StatelessModel(lambda: GmdhRegressor.paper(
                max_layers=cfg.gmdh_max_layers, max_neurons=cfg.gmdh_max_neurons,
                alpha=cfg.gmdh_alpha, split="tail", ridge=1e-6))  # fmt: skip

    elif name == "rbf":

        def factory() -> ComponentModel:
            return StatelessModel(lambda: RbfNet(n_centers=cfg.rbf_centers))

    elif name == "bp-parallel":

        def factory() -> ComponentModel:
            return StatelessModel(lambda: BpNet(n_hidden=cfg.bp_hidden, n_epochs=cfg.bp_epochs))

    else:  # mlp: P1 works on the horizontal motion only

        def factory() -> ComponentModel:
            return NarxModel(lambda: NarxMLP(
                n_hidden=cfg.mlp_hidden, n_input_lags=1, n_output_lags=1,
                max_nfev=cfg.mlp_max_nfev))  # fmt: skip

        components = (0, 1, 3, 4)
        budget = cfg.mlp_max_samples
    return LearnedBridge(
        name, cfg, factory, features, components,
        pseudo_gnss=name == "gmdh-pseudo", max_samples=budget,
    )  # fmt: skip

