"""The ground station: CLI now; missions, MAVLink link, fleet and API in later work."""
