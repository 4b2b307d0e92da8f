"""Online studies: a rating protocol exported as a static jsPsych study, and its data imported back.

:func:`export_web` writes the study folder (trial lists equal to the lab runner's, jsPsych vendored
from npm, images at the protocol's screen geometry); :func:`import_web` turns the browser's
``_beh.tsv`` files into the lab's BIDS layout after :func:`read_session_file` has checked them as
hostile input.
"""

from experiments.web.export import WEB_COLUMNS, WebExport, export_web, participant_slots, web_columns, web_refusal
from experiments.web.importer import ImportedSession, import_web
from experiments.web.session_file import ImportContext, SessionFile, import_context, read_session_file

__all__ = ["WEB_COLUMNS", "WebExport", "export_web", "participant_slots", "web_columns", "web_refusal",
           "ImportedSession", "import_web", "ImportContext", "SessionFile", "import_context", "read_session_file"]
