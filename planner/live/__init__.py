"""The live replanner, on the same engine: reported objects and the replan of the
UAVs they touch, in flight."""
