"""The driver: what runs a simulation from a scene file, between the engine and the scenes.

Owns the run loop with progress, stop signals and scheduled checkpoints (`runloop`), the plain
run of a scene file (`plain`), the generic staged run and its table operations (`stages`), the
observables it records (`observables`, `cycles`), the results files it writes in the format of
`pdem.format.schema` (`results`) and the run's account for its post-processing
(`pdem.format.run`, which ``pdem run`` hands to ``python -m analysis summary``). Layers: scenes and
jobs → driver → engine; the engine never imports the driver, the driver never imports the scenes
and neither imports analysis.
"""
