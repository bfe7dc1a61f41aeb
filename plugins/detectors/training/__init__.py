"""Training and evaluation of the ``edgebox-cnn`` head classifier.

:mod:`.sampling` (frames and crops) and :mod:`.evaluate` (precision/recall) need only NumPy and
OpenCV; :mod:`.model` and :mod:`.train` need PyTorch (the ``train`` extra) and are imported only
by ``trackfw train detector``.
"""
