"""The flight fuzzer: whole flights through the in-process service, drawn from a seed.

A seed draws a scenario (crossing, random traffic, a swap through a gap), the vehicles'
faults (loss, latency, jitter, duplication, reordering, a late take-off) and an
operator who acts at random moments (holds, continues, lands or sends home one vehicle,
aborts, reports an object, restarts the service). The flight runs on the virtual clock,
so it replays exactly, and every invariant is checked as it flies (`invariants`).

    python -m tests.fuzz --seed 1234           # replay one flight, saying what it saw
    python -m tests.fuzz --seeds 0:10000       # a campaign (--scheduler tcp://... on Dask)
"""
