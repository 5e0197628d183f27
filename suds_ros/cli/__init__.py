"""The ``suds`` command line."""
