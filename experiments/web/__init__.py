"""Online studies: a rating protocol exported as a static jsPsych study, and its data imported back.

:func:`export_web` writes the study folder (trial lists equal to the lab runner's, jsPsych vendored
from npm, images at the protocol's screen geometry); :func:`import_web` turns the browser's
``_beh.tsv`` files into the lab's BIDS layout.
"""

from experiments.web.export import WEB_COLUMNS, WebExport, export_web, participant_slots, web_columns, web_refusal
from experiments.web.importer import ImportedSession, import_web

__all__ = ["WEB_COLUMNS", "WebExport", "export_web", "participant_slots", "web_columns", "web_refusal",
           "ImportedSession", "import_web"]
