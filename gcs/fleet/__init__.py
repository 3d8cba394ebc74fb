"""A fleet flight: several vehicles flying one plan together."""
