"""Contact laws. One module per law; each provides N_PARAMS, HISTORY_WIDTH and force loops for
the sphere–sphere, sphere–wall and sphere–facet geometries with the same signatures."""
