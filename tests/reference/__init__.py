"""Reference implementations used only as test oracles."""
