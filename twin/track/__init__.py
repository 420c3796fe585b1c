"""The twin over time: campaigns of records under changing operation, and their tracking.

:func:`~twin.track.schedule.read_schedule` reads a campaign's schedule, :func:`~twin.track.campaign.campaign`
simulates its records through the FMU (``twin campaign``); :func:`~twin.track.tracker.track` follows a unit
over a folder of records, raises alarms and names what changed (``twin track``), and
:func:`~twin.report.tracking.write_report` draws it.
"""

from twin.track.campaign import campaign
from twin.report.tracking import write_report
from twin.track.schedule import Schedule, read_schedule
from twin.track.tracker import alarms_json, track

__all__ = ["Schedule", "alarms_json", "campaign", "read_schedule", "track", "write_report"]
