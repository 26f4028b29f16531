"""Measuring corpora for the learner, written apart from it: a seeded stress generator and the shared real tracks.

``case`` holds the common types and the recording writer; ``stress`` and ``real`` build cases; ``score`` compares a
learned chain with a case's truth; ``show`` prints a summary (``python -m bench.learn_corpus.show``).
"""

from bench.learn_corpus.case import START_NS, Case, TruthPrimitive, resample, write_case

__all__ = ["START_NS", "Case", "TruthPrimitive", "resample", "write_case"]
