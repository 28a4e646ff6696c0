"""Training: crop datasets and leak-free splits (:mod:`.dataset`), feature extraction and
fitting a model (:mod:`.fit`), hard-negative mining (:mod:`.mine`)."""
