#!/usr/bin/env python3
"""Grouped cross-validation of indoor/outdoor classifiers on the committed
scene-class references (inference/data/scene_refs.bin): 10 folds by group
(a panorama, a Blender scene with its mirror, a rendered pair), accuracy per
source. How the scene classifier's kind and C were chosen (docs/scene_class.md).
Needs Debian's python3-sklearn (not installed by scripts/setup.sh: a study tool).

    /usr/bin/python3 scripts/study/scene_class_cv.py [inference/data/scene_refs.bin]
"""
import struct
import sys

import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC


def load(path):
    b = open(path, 'rb').read()
    if b[:8] != b'PCSCENE\0':
        sys.exit(f'{path}: not a scene reference set')
    o = 8
    _, ng = struct.unpack_from('<II', b, o)
    o += 8
    groups = []
    for _ in range(ng):
        (n,) = struct.unpack_from('<I', b, o)
        o += 4
        groups.append(b[o:o + n].decode())
        o += n
    n, length = struct.unpack_from('<II', b, o)
    o += 8
    x = np.zeros((n, length), np.float32)
    y = np.zeros(n, int)
    g = np.zeros(n, int)
    for i in range(n):
        y[i] = b[o]
        (g[i],) = struct.unpack_from('<i', b, o + 1)
        x[i] = np.frombuffer(b, np.float32, length, o + 5)
        o += 5 + 4 * length
    return x, y, g, groups


def knn_share(xtr, ytr, xte, k=7):
    d = ((xte[:, None, :] - xtr[None, :, :]) ** 2).sum(-1)
    idx = np.argsort(d, 1)[:, :k]
    w = np.where(ytr[idx] == 1, 1 / ytr.sum(), 1 / (len(ytr) - ytr.sum()))
    return (w * (ytr[idx] == 1)).sum(1) / w.sum(1) - 0.5


def main():
    x, y, g, groups = load(sys.argv[1] if len(sys.argv) > 1 else 'inference/data/scene_refs.bin')
    source = np.array(['render' if gi < 0 else 'blender' if groups[gi].startswith('blender/') else 'panorama' for gi in g])
    group = np.array([1000 + i // 2 if gi < 0 else gi for i, gi in enumerate(g)])
    unique = np.unique(group)
    perm = np.random.RandomState(0).permutation(len(unique))
    fold = np.array([dict(zip(unique, perm % 10))[v] for v in group])
    classifiers = {
        'k-NN 7, balanced': knn_share,
        'logistic C=0.1': lambda a, b, c: make_pipeline(StandardScaler(), LogisticRegression(
            C=0.1, max_iter=2000, class_weight='balanced')).fit(a, b).decision_function(c),
    }
    for c_value in (0.3, 1, 3):
        classifiers[f'SVM RBF C={c_value}'] = lambda a, b, c, cv=c_value: make_pipeline(StandardScaler(), SVC(
            C=cv, gamma='scale', class_weight='balanced')).fit(a, b).decision_function(c)
    for name, fit in classifiers.items():
        score = np.zeros(len(y))
        for f in range(10):
            score[fold == f] = fit(x[fold != f], y[fold != f], x[fold == f])
        pred = (score >= 0).astype(int)
        cells = []
        for s in ('render', 'panorama', 'blender'):
            m = source == s
            cells.append(f'{s} {np.mean(pred[m] == y[m]):.2f} (in {np.mean(pred[m & (y == 1)] == 1):.2f}, '
                         f'out {np.mean(pred[m & (y == 0)] == 0):.2f})')
        print(f'{name:18s} ' + ' | '.join(cells))


if __name__ == '__main__':
    main()
