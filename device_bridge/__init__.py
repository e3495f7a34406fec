"""Device bridge: the CAN protocol, the leg's firmware and host link, transports, the simulated prosthesis (sim/) and the
model on the bench (bench/)."""
