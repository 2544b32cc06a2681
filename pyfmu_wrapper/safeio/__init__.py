"""Writing outputs without ever losing what the tool did not write: whole result folders
(:mod:`.folder`) and single files in a shared folder (:mod:`.files`), on the folder inventories and
markers of :mod:`.tree`."""

from .folder import ResultFolder
from .tree import Diverted, OutputError, abs_path

__all__ = ["Diverted", "OutputError", "ResultFolder", "abs_path"]
