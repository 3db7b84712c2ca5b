"""The blind benchmark of the gap diagnosis: ``gen`` writes labelled cases from its own physics,
``check`` diagnoses them without the labels and scores the verdicts.

Kept apart on purpose: ``tools.simgap`` never imports this package (it must not see how cases are
made), and ``gen`` imports nothing from ``simgap``; only ``check`` calls the diagnosis.
"""
