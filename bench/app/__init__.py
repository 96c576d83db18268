"""The composition root: bench configuration to devices, engine, store, analysis and front ends."""
