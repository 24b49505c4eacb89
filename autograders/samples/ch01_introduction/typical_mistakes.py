# Answer cells of the "typical mistakes" sample submission of ch01_introduction.
#
# Chapter 1 has no autograded exercise (its graded part is written questions and an open task,
# marked by hand), so there is no answer cell to replace. Its two former warm-up exercises,
# `formation.image_memory_bits` and `formation.quantize` (§2.11), and their typical mistake now
# live in Chapter 2: see ../ch02_image_formation/typical_mistakes.py.
# This file is data for the demo and its tests, not a module to import.
