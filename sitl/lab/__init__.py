"""The offline laboratory: closed-loop flights of ``sitl.plant`` under the control core, in one
process and faster than real time — the simulation runner, metrics, figures, the paper's
experiments and claims, Monte-Carlo sweeps and gain tuning. Uses ``sitl.plant``, never
``sitl.autopilot``."""
