"""Layer 4, files: everything read from or written to disk.

``task_files`` (task YAML), ``simulation_config`` (the typed ``simulation:`` block),
``guidance_scripts`` (``drake-lfd record`` scripts), ``demonstration_logs`` (RTDE
CSV), ``library`` with ``library_manifest`` and ``feature_cache``, ``policy_files``,
``plan_json`` and ``pose_records`` (JSON documents), ``atomic_files``, ``file_lock``
(the library's advisory lock), ``yaml_checks``.
"""
