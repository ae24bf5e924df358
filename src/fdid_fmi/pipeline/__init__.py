"""The steps behind the public API (:mod:`fdid_fmi.api`) that the ``fdid`` commands and the
fleet's manifests share: the identification options (:mod:`.identify`), their value parsers
(:mod:`.argtypes`) and reading traces with a column map, units and ranges (:mod:`.traces`)."""
