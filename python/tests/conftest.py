"""Under ctest (GCMAP_PYTHON_REQUIRED=1) a module that fails to import fails the run; by hand, the
tests skip with a message when the package is not built (each file uses pytest.importorskip)."""
import os

if os.environ.get("GCMAP_PYTHON_REQUIRED"):
    import gcmap  # noqa: F401  (an ImportError here is the failure to report)
