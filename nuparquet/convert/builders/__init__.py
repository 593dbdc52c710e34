"""One module per dataset `nuparquet convert` builds; each exports `BUILDER` (see `nuparquet.convert.builder`; listed in `nuparquet.convert.registry`)."""
