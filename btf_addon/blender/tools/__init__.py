"""Operators that bring materials in and make them smaller: File › Import › BTF Material
(``import_btf.py``), drag and drop (``file_handler.py``) and Compress BTF
(``compress.py``)."""
