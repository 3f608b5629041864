"""Paths and the data-set reader for the battery fit. Nothing is written into the repository:
the cache and the results go to OUT (env BATTERY_OUT, default <tmp>/dronewatt-battery)."""
import os, tempfile
import pandas as pd
_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
DATA = os.environ.get('DRONEWATT_DATA') or os.path.join(_ROOT, '..', 'shared', 'data', 'm100', 'flights.csv.gz')
PARAMS = os.path.join(os.path.dirname(os.path.abspath(DATA)), 'parameters.csv')
OUT = os.environ.get('BATTERY_OUT') or os.path.join(tempfile.gettempdir(), 'dronewatt-battery')
def out(name):
    os.makedirs(OUT, exist_ok=True); return os.path.join(OUT, name)
def load():
    if not os.path.exists(DATA): raise SystemExit(f'{DATA}: no such file (set DRONEWATT_DATA)')
    p = out('cache.pkl')
    if os.path.exists(p): return pd.read_pickle(p)
    df = pd.read_csv(DATA, usecols=['flight','time','battery_voltage','battery_current','position_z','route','speed','payload'])
    df.to_pickle(p); return df
