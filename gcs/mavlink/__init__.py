"""The MAVLink client: one vehicle at a time, over an injected byte transport."""
