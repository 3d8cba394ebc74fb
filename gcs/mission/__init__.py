"""The mission domain: plans to MAVLink missions, their files, geodesy and pacing."""
