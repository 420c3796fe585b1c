"""The twin over time: campaigns of records under changing operation, and (to come) their tracking.

:func:`~twin.track.schedule.read_schedule` reads a campaign's schedule, :func:`~twin.track.campaign.campaign`
simulates its records through the FMU (``twin campaign``).
"""

from twin.track.campaign import campaign
from twin.track.schedule import Schedule, read_schedule

__all__ = ["Schedule", "campaign", "read_schedule"]
