"""Chapters 9–10 — image classification and image representations (§9.5–9.8, §10.1–10.3).

A linear softmax classifier written from its parts (scores, softmax, cross-entropy, gradients
checked numerically, mini-batch SGD, top-k accuracy), k-nearest neighbours on raw pixels,
and a bag of visual words (k-means codebook, word histograms) over dense local descriptors;
and the chapter's measured exercise: ``train_digit_classifier``, graded by the accuracy it
reaches on held-out digits.

Conventions: samples are the rows of ``X`` ``(N, D)`` (flattened images or descriptors);
labels are integer arrays ``0..C−1``; ``W`` is ``(C, D)`` so that the scores are
``X @ W.T + b`` (note that ``cvkit.nn.linear_forward`` uses the layer convention ``(D, C)``).
Functions that draw random numbers (``sgd_train``, ``kmeans``) take ``rng``. Everything is
float64, and inputs are never modified.

>>> import numpy as np
>>> from cvkit import learn
>>> learn.softmax(np.array([1e4, 0.0, -1e4]))
array([1., 0., 0.])
"""
from ._linear import (
    linear_scores,
    softmax,
    cross_entropy,
    linear_loss_and_grad,
    numerical_gradient,
    sgd_train,
    top_k_accuracy,
)
from ._neighbours import knn_predict
from ._clustering import kmeans, bovw_histogram
from ._descriptors import dense_descriptors
from ._digits import train_digit_classifier

__all__ = [
    "linear_scores",
    "softmax",
    "cross_entropy",
    "linear_loss_and_grad",
    "numerical_gradient",
    "sgd_train",
    "top_k_accuracy",
    "knn_predict",
    "kmeans",
    "bovw_histogram",
    "dense_descriptors",
    "train_digit_classifier",
]
