"""Analysis of a study folder: the paper's Tables II–IV, the statistics of Sect. VI, Fig. 4, learning
curves and (from a ``benchmark-pl`` folder) Fig. 3, gathered in ``handover report``.

The statistics and tables are plain functions over the tidy tables of ``session_store.export`` so that
a notebook can call them on ``read_table`` output; see ``docs/analysis.md``.
"""
