"""``.osim`` to MJCF: one handler per OpenSim element family, the builder that assembles them,
the fits against OpenSim, and the conversion report.

``convert("arm26.osim", "out/")`` writes ``out/arm26.xml`` with its meshes and report; pass a
:class:`ConvertOptions` to change how. This subpackage never imports :mod:`o2m.validate`.
"""

from o2m.convert.converter import Conversion, ConvertOptions, conversion_key, convert, convert_once
from o2m.convert.report import ConversionReport

__all__ = ["Conversion", "ConversionReport", "ConvertOptions", "conversion_key", "convert", "convert_once"]
