"""Data shipped with the channel worker: the bundled airfield scene and its generator."""
