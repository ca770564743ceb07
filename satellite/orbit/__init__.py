"""The orbit: the Kepler model and the truth flow, elements, event location, arcs (compiled or not) and a run."""
