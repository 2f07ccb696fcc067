"""HTTP skin over the engine."""
