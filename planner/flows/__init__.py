"""The flows over one planning engine: the planning state, the paper's flow
(Algorithm 1: white hole, black hole, wormhole) and the anytime flow, side by side
in `policies`."""
