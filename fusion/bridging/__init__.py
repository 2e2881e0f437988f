"""GNSS-outage bridging (papers P0-P3): learn the INS error while GNSS is good, correct the INS
while it is not.

One job per module:

- :mod:`fusion.bridging.interface` — what :class:`fusion.filter.NavFilter` and a strategy hand
  each other (epochs, INS errors, pseudo-fixes, output corrections, status), the
  :class:`~fusion.bridging.interface.Bridge` protocol and the ``none`` strategy;
- :mod:`fusion.bridging.virtual_outages` — the virtual-outage INS copies that give the learned
  strategies drift samples while GNSS is good;
- :mod:`fusion.bridging.features` — the network inputs of one pair or epoch;
- :mod:`fusion.bridging.models` — one component's regressor behind a uniform face, clipped to
  its training range;
- :mod:`fusion.bridging.gate` — the fallback gate that switches each component's correction
  on only while it wins on outages it never saw;
- :mod:`fusion.bridging.learned` — the learned strategy (training inside the fusion loop);
- :mod:`fusion.bridging.registry` — every method by name (:func:`~fusion.bridging.registry.
  make_bridge`, :data:`~fusion.bridging.registry.BRIDGE_METHODS`).
"""
