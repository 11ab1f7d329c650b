"""The registered extraction methods, one module each (``fullfit`` is a package beside this
one): importing this package registers them, in the order of the ``--method`` choices.

Adding a method is adding its module here and one import line below; it follows the
convention of :mod:`vetica_cli.extraction.base` (:func:`vetica_cli.testing.check_method`
runs it).  A method's own checks and error bars live with it (the tap family's in
:mod:`.tapchecks` and :mod:`.tapsigmas`, the whole-cycle fit's in
:mod:`vetica_cli.extraction.fullfit.checks`).
"""

# isort: off
from . import vetica  # noqa: F401  (registers 'vetica')
from . import vetica_prestress  # noqa: F401  (registers 'vetica-prestress')
from .. import fullfit  # noqa: F401  (registers 'full')
from . import observables  # noqa: F401  (registers 'observables')
from . import dmt_fit  # noqa: F401  (registers 'dmt-fit')
from . import peak_force  # noqa: F401  (registers 'peak-force')
# isort: on
