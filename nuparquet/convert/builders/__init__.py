"""One module per dataset `nuparquet convert` builds; each exports `BUILDER` (see `nuparquet.convert.registry`)."""
