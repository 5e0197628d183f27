"""Physics: resistive-force chains, the 1-D swimmers, simulation, streaming, effects."""
