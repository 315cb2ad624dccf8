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

A spec may say what each run is with ``run:``: ``slam`` (the default) or ``localize``. A
``localize`` sweep runs ``pfslam localize`` on each log's ``map`` (a map.yaml or a ``pfslam
slam`` output folder, relative to the spec's folder like every path, ``{seed}`` allowed), its
settings are keys of the localize section (:class:`~pfslam.config.LocalizerConfig`, ``pfslam
dump-config localize``), its seed the filter's::

    run: localize
    logs:
      - name: rough1
        path: walks/rough1/train_lidar0.mat
        joint: walks/rough1/train_joint0.mat
        ground_truth: walks/rough1/groundtruth.tum
        map: walks/rough1/map.yaml
        args: ["--calibrate"]                 # or --global, --initial-pose X,Y,DEG, ...
    seeds: [0, 1, 2]
    settings:
      sigma_hit_adapt: [false, true]

- :func:`spec.load_spec` reads and validates a spec (every problem is an :class:`InputError`
  naming the spec file and the key); :func:`jobs.make_jobs` expands it into one :class:`Job`
  per log × setting combination × seed, each with its own run folder
  ``OUT/runs/<log>/<settings-slug>/seed<k>/``.
- :func:`runner.run_job` executes one job: the real ``pfslam slam`` (or ``pfslam localize``) in
  a fresh subprocess (so a crash or a kill takes only that run down, and its peak memory is
  its own), its settings in the run folder's ``sweep_config.yaml`` (the section of its
  command), then reads the run's ``run.json`` (and scores the relations, if the log has them)
  into a small row that it also writes to the run folder as ``result.json``: a run is done
  when that file is there. A slam run's accuracy is run.json's ``metrics.SLAM``, a localize
  run's its ``metrics.estimate``, with the localize columns of
  :data:`~pfslam.sweep.columns.LOCALIZE_METRICS` (``settle_s``, ``recoveries``, ``sigma_hit``)
  from its ``filter`` section; the map-agreement columns stay empty for it. Only the job (paths, settings, seed) goes to a worker and only the row comes
  back: the logs are read where they are.
- :func:`runner.run_jobs` runs jobs on Dask (a local cluster of processes, or an existing
  scheduler), reporting each row through a callback as it arrives.
- :func:`build_table`, :func:`summarize` and :func:`plot_summary` turn rows into the
  table (``results.csv``/``.parquet``), per-combination statistics and ``summary.png`` (a
  localize sweep's settle time among them).

Nothing here prints.

Modules: :mod:`~pfslam.sweep.spec` (the spec, its setting combinations' names; imports only
config and errors), :mod:`~pfslam.sweep.jobs` (the jobs of a spec, their run folders' files),
:mod:`~pfslam.sweep.columns` (the table's columns, the metrics of each kind of run),
:mod:`~pfslam.sweep.runner` (subprocesses, Dask), :mod:`~pfslam.sweep.table` (pandas, the picture),
:mod:`~pfslam.sweep.whole` (a whole sweep: plan, run, table).
Nothing here prints, and nothing imports a filter: a run is a ``pfslam slam`` or ``pfslam
localize`` process.
"""
