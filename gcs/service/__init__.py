"""The planning and flight service: REST + WebSocket API, storage, console."""
