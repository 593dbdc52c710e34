"""The map expansion as data: GeoParquet helpers (`geo`), lane centreline discretisation exactly as the devkit's
`discretize_lane` (`centerlines`), and vectorised map queries with devkit parity (`queries`)."""
