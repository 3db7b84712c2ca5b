"""The blind benchmark of the gap diagnosis: ``gen`` writes labelled cases from its own physics,
``check`` diagnoses them without the labels and scores the verdicts.

``wander`` is a second generator written apart from both (bias random walk, bias instability,
whole-LSB output; the situations of issue 22) and ``wandercheck`` scores it, running the diagnosis
only through ``python -m tools gap``'s front door.

Kept apart on purpose: ``tools.simgap`` never imports this package (it must not see how cases are
made), ``gen`` imports nothing from ``simgap`` and ``wander`` nothing of ours at all; only ``check``
and ``wandercheck`` call the diagnosis.
"""
