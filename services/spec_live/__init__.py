"""The requirements monitored live: the specification's requirement properties evaluated
while a fleet runs, a property flagged *violated* as soon as it is (docs/spec.md, "The live
monitor").

- services/spec_live/live.py: ``LiveMonitor``, the properties that can be violated as they
  happen, fed communicates in arrival order and evaluated in causal order as far as known;
- services/spec_live/sink.py: ``RequirementsSink``, the traffic recorder's side: each
  communicate it wrote, decoded and fed, each new violation appended to the run folder's
  ``flags.jsonl`` (services/recorder/flags.py).
"""
