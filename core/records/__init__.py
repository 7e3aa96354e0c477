"""The records a run is made of and writes: canonical signals (signals),
tasks and outcomes (outcome), the model audit (audit), engine findings
(findings), the reference inputs an engine run read (engine_inputs), and
output files written whole (outputs)."""
