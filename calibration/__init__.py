"""Recordings, vision and the inverse problems that fit the bench to them (issues 5 and 6)."""
