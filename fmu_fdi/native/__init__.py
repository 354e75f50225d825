"""The native diagnostic FMU: C99 runtime sources (``c/``) and the design emitter (:mod:`.emit`)."""
from pathlib import Path

#: Folder of the C sources shipped in a native FMU.
C_DIR = Path(__file__).parent / "c"
#: The runtime's translation units (the FMI glue adds its own); design_data.c is generated.
RUNTIME_SOURCES = ("fdi_linalg.c", "fdi_evaluation.c", "fdi_decision.c", "fdi_rls.c", "fdi_runtime.c")
RUNTIME_HEADERS = ("fdi_runtime.h", "fdi_design.h", "fdi_internal.h")
