"""The vehicle thermal system over a drive cycle (issue 15; so far the drive cycles)."""
