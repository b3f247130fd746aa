"""Certification-style test campaigns: procedures x systems x parameter variations x seeds,
each case judged against acceptance criteria that name the requirement they verify, run on Dask
(a local cluster by default, or an existing one) with every case in a process of its own.

Modules, one idea each:
  reader    the campaign file (TOML) and its checks
  spec      a campaign, its cases (deterministic ids and seeds) and their tasks
  case      one case in this process (simulate, calibrate, judge); ``python -m`` entry point
  criteria  acceptance criteria on a case's numbers
  isolate   the Dask task: a case in a child process with a timeout (crash/hang -> errored)
  store     the output folder: atomic per-case records, what is done, the manifest file
  execute   the Dask cluster or client, submission and the completion loop
  progress  done / failed / running and the time left, on the terminal
  manifest  what an auditor needs to trust the record: hashes, versions, seeds, host, times
  junit     JUnit XML; summary: the JSON summary and the regression verdict
  html      the HTML report
"""
