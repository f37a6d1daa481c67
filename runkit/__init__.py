"""runkit: the run machinery every tier shares, with no physics.

- :mod:`runkit.limits`: the physical limits of every input, each with its reason;
- :mod:`runkit.params`: one parameter schema (type, unit, bounds from limits or from the other
  parameters), one check, one refusal, the command-line options;
- :mod:`runkit.command`: a command's exit statuses, one-line messages, signals;
- :mod:`runkit.run`: long runs (checkpoint and resume, deferred signals, held numpy warnings,
  progress, the output folder and its manifest);
- :mod:`runkit.ida`: SUNDIALS IDA with named events, its output captured, one failure text.
"""
