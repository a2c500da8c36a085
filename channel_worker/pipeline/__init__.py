"""The channel pipeline: one channel's frame, stage by stage (docs/pipeline.md,
docs/architecture.md).

render.py calls the stages in order; contract.py holds what they hand each other. The compiled
kernels are cached per version of the pipeline's sources (kernel_cache.py), chosen here, before
any stage module defines a kernel.
"""

from __future__ import annotations

from .kernel_cache import use_kernel_cache

use_kernel_cache()
