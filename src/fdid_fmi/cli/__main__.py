"""``python -m fdid_fmi.cli`` runs the ``fdid`` command."""
import sys

from . import main

sys.exit(main())
