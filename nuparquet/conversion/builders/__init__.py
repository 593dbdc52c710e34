"""One module per dataset `nuparquet convert` builds; each exports `BUILDER` (see `nuparquet.conversion.builder`; listed in `nuparquet.conversion.registry`)."""
