# Answer cells of the "typical mistakes" sample submission of ch01_introduction.
#
# `cvkit demo` builds the sample student `sample_mistakes` from the solutions of the source
# notebook, then replaces each answer cell named below (`# %% <grade_id>`) by the code that
# follows: wrong answers students really write. Chapter 1 has only two warm-up exercises, so
# one carries a typical mistake and the other is left unattempted.
# This file is data for the demo and its tests, not a module to import.

# %% quantize_answer
@student("formation.quantize")
def quantize(image, bits, vmax=1.0):
    """Rounds with the school rule floor(t + 0.5): half-way values go up, not to the even level."""
    levels = 2 ** bits - 1
    t = np.clip(np.asarray(image, dtype=float), 0, vmax) / vmax * levels
    return np.floor(t + 0.5) / levels * vmax

# %% image_memory_bits_answer
@student("formation.image_memory_bits")
def image_memory_bits(width, height, bits_per_pixel):
    """Not attempted."""
    # YOUR CODE HERE
    raise NotImplementedError()
