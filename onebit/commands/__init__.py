"""The ``onebit`` subcommands, one module per group: each registers its parsers
(``add_*_command(s)(sub)``, called by :func:`onebit.cli.build_parser`) and holds the functions
they call (``_cmd_*``: arguments in, the package's configs and functions called, a summary
printed). Option defaults come from the functions and configs the commands call
(:func:`onebit.commands.options.default_of`), never written twice."""
