"""The building model: shear buildings on an isolation layer (masses, story stiffness, damping, the
isolator's law; modal analysis, TOML files) and the checks of a posterior against a building."""
