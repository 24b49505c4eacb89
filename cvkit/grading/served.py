"""What the grader computes for graded code: the building blocks and data an exercise may use.

Graded code runs in the sandbox with no reference code (:mod:`cvkit.sandbox`); when it calls
an allowed building block or one of :mod:`cvkit.data`'s loaders, the value is computed outside,
by the reference server (:mod:`cvkit.sandbox.reference_server`). Which ids may be served is a
rule of grading, kept here: the server only computes what this module allows.
"""
from __future__ import annotations

__all__ = ["DATA_SOURCES", "DATA_TRANSFORMS", "DATA_LOADERS", "ANSWERING_SOURCES", "served_helpers"]

#: loaders of :mod:`cvkit.data` that make data from numbers alone (images, datasets, synthetic
#: scenes; never the readers that take a file path): served to graded code in every exercise
#: unless :data:`ANSWERING_SOURCES` says one is that exercise's answer
DATA_SOURCES = (
    "astronaut", "brick", "camera", "chelsea", "coffee", "coins", "moon", "text", "digits", "textures",
    "disk_image", "square_image", "polygon_image", "segments_image", "step_edge", "step_signal",
    "oriented_step_image", "part_outline", "part_scene", "part_template", "render_chessboard",
    "random_board_poses", "stereo_motorcycle",
)
#: loaders that compute something from an image the student passes (add noise, halve, measure
#: PSNR, stack noisy frames): each is an exercise's algorithm or a step of one
#: (``noise.add_gaussian`` *is* ``with_gaussian_noise``), so graded code is never served them —
#: they are for the notebooks' demos, which do not run at grading time
DATA_TRANSFORMS = ("noisy_stack", "resize_half", "with_gaussian_noise", "with_impulse_noise", "psnr")
#: every loader the sandbox holds a stand-in for (a refused one says so by name)
DATA_LOADERS = DATA_SOURCES + DATA_TRANSFORMS
#: data sources that would be, by themselves, the answer of some exercise: data source →
#: algorithm ids in which it is not served. ``tests/sandbox/test_allowed_helpers.py`` calls every served
#: helper of every check as the whole answer, and none passes; the images below are the clean
#: pictures of Chapter 3's measured denoiser (``filters.denoise``), whose crops a graded answer
#: could otherwise look up instead of denoising (``tests/library/test_checks_ch03.py`` keeps the list
#: equal to ``cvkit.filters._denoise.IMAGES``).
ANSWERING_SOURCES: dict[str, tuple[str, ...]] = {
    name: ("filters.denoise",) for name in ("camera", "coins", "astronaut", "coffee", "chelsea", "text", "brick")
}


def served_helpers(algorithm_id: str, building_blocks: tuple = ()) -> tuple[str, ...]:
    """The ids the grader computes for graded code of the exercise ``algorithm_id``: its check's
    ``building_blocks`` (``Check.allowed``, never the exercise itself) and the data sources that
    are not its answer (``"data.camera"``, …)."""
    blocks = tuple(block for block in building_blocks if block != algorithm_id)
    return blocks + tuple(f"data.{name}" for name in DATA_SOURCES
                          if algorithm_id not in ANSWERING_SOURCES.get(name, ()))
