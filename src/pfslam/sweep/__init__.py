"""Sweeps: one command runs many logs × seeds × settings and collects one table.


A *spec* (YAML) names the logs, the seeds and the settings to vary::

    logs:
      - name: intel
        path: ../data/intel.gfs.log.gz       # relative to the spec's folder
        odometry: "synthetic:{seed}"          # {seed} becomes each run's seed
        relations: ../data/intel.relations
        time_offset: 976052857.338
    seeds: {from: 0, to: 4}                   # or a list
    settings:                                 # any config key, dotted; every combination runs
      local_search.enabled: [false, true]
      particles: {from: 50, to: 150, step: 50}

- :func:`spec.load_spec` reads and validates a spec (every problem is an :class:`InputError`
  naming the spec file and the key); :func:`spec.make_jobs` expands it into one :class:`Job`
  per log × setting combination × seed, each with its own run folder
  ``OUT/runs/<log>/<settings-slug>/seed<k>/``.
- :func:`runner.run_job` executes one job: the real ``pfslam slam`` in a fresh subprocess (so a
  crash or a kill takes only that run down, and its peak memory is its own), then reads
  the run's ``run.json`` (and scores the relations, if the log has them) into a small row
  that it also writes to the run folder as ``result.json``: a run is done when that file
  is there. Only the job (paths, settings, seed) goes to a worker and only the row comes
  back: the logs are read where they are.
- :func:`runner.run_jobs` runs jobs on Dask (a local cluster of processes, or an existing
  scheduler), reporting each row through a callback as it arrives.
- :func:`build_table`, :func:`summarize` and :func:`plot_summary` turn rows into the
  table (``results.csv``/``.parquet``), per-combination statistics and ``summary.png``.

Nothing here prints.

Modules: :mod:`~pfslam.sweep.spec` (the spec and its jobs; imports only config and errors),
:mod:`~pfslam.sweep.runner` (subprocesses, Dask), :mod:`~pfslam.sweep.table` (pandas, the picture),
:mod:`~pfslam.sweep.whole` (a whole sweep: plan, run, table).
Nothing here prints, and nothing imports a filter: a run is a ``pfslam slam`` process.
"""
