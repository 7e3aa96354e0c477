"""OpenSim (Simbody) engine: adapter, model, run, audit and findings."""
