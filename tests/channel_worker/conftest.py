"""Fixtures shared by the channel worker tests (the scene builders live with the pipeline tests)."""

from .pipeline.conftest import box_model_factory, make_scene  # noqa: F401
