import sys

from tactilab.cli.main import main

sys.exit(main())
