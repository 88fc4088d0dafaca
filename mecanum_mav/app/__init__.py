"""The application: the companion process (a thin shell around the core), the command line,
the demo and the figures."""
