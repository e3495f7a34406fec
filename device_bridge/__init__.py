"""Device bridge: CAN protocol, transports and the simulated prosthesis (not built yet; see issue 5)."""
