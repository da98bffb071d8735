# The search's table: per run, route types completed in more than half their runs (of 7), runs
# completed and collisions (of 35), per route, and the training's wall time. Usage: python3 summary.py
import json, glob, os, sys
rows = []
for d in sorted(glob.glob(os.path.join(os.path.dirname(os.path.abspath(__file__)), '*-s*'))):
    for f in ['eval.json', 'eval-best.json']:
        p = os.path.join(d, f)
        if not os.path.exists(p): continue
        try: r = json.load(open(p))
        except Exception: continue
        a = [x for x in r['agents'] if x['kind'] == 'checkpoint'][0]
        comp = sum(x['completed'] for x in a['routes']); col = sum(x['collisions'] for x in a['routes'])
        per = ' '.join(f"{x['route'][:6]}:{x['completed']}" for x in a['routes'])
        kinds = {}
        for x in a['routes']:
            for k in x['collision_kinds']: kinds[k] = kinds.get(k, 0) + 1
        wall = ''
        t = os.path.join(d, 'wall.txt')
        if os.path.exists(t):
            for line in open(t):
                if 's wall' in line: wall = line.strip()
        print(f"{os.path.basename(d):28s} {f[:-5]:10s} maj {a['routes_completed_majority']}/7 comp {comp:2d}/35 col {col:2d} {per} {kinds} {wall}")
