"""What the operator's station put into a bag: decisions about hits and the session's metadata.

The recorder records fmm/impact_decisions and fmm/session_info like any topic, and writes the
newest session metadata into metadata.yaml (custom_data `fmm.session`) when the bag closes.
These read them back for replay, the report and campaigns: the decisions in the
order they were made (the newest per hit wins: `core.signal.judging.latest`), the metadata
from metadata.yaml, else (a bag a crash left without one) from the last recorded message.
"""

from pathlib import Path

from fmm_ros.constants import DECISIONS_TOPIC, SESSION_INFO_TOPIC
from fmm_ros.core.signal.judging import Decision
from fmm_ros.errors import FmmError
from fmm_ros.io import session_info
from fmm_ros.io.bags.definitions import IMPACT_DECISION, SESSION_INFO
from fmm_ros.io.bags.errors import MissingTopicError
from fmm_ros.io.bags.metadata import read_information
from fmm_ros.io.bags.reader import BagReader


def bag_decisions(reader: BagReader) -> tuple[list[Decision], list[str]]:
    """The recorded decisions in order, and a problem for each malformed one (left out)."""
    decisions, problems = [], []
    try:
        for _, msg in reader.decoded(DECISIONS_TOPIC, IMPACT_DECISION):
            try:
                decisions.append(
                    Decision(
                        int(msg.impact_id),
                        msg.verdict,
                        msg.decided_by,
                        msg.reason,
                        msg.mode,
                        int(msg.trigger_sample_index),
                        msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec,
                    )
                )
            except FmmError as error:
                problems.append(f'a recorded decision was left out: {error}')
    except MissingTopicError:
        pass
    return decisions, problems


def bag_session_info(
    path: str | Path, reader: BagReader | None = None
) -> session_info.SessionInfo | None:
    """The session's metadata a bag holds, or None when it holds none.

    reader: the bag already open (its messages are read only when the metadata file holds
    none); without one, the bag is opened here. BadInputError when what it holds is not valid
    metadata.
    """
    path = Path(path)
    folder = path if path.is_dir() else path.parent
    text = (read_information(folder).get('custom_data') or {}).get(session_info.SESSION_KEY)
    if text:
        return session_info.from_json(text)
    if reader is None:
        with BagReader(path, strict=False) as opened:
            return _last_session_info(opened)
    return _last_session_info(reader)


def _last_session_info(reader: BagReader) -> session_info.SessionInfo | None:
    """The last SessionInfo message a bag recorded, or None."""
    last = None
    try:
        for _, msg in reader.decoded(SESSION_INFO_TOPIC, SESSION_INFO):
            last = msg
    except MissingTopicError:
        return None
    if last is None:
        return None
    return session_info.from_message(last)
