import numpy as np
from scipy.signal import lfilter
NC=6
DT=0.1
class Curve:
    """per-cell OCV table: v knots -> pack energy above floor (Wh)"""
    def __init__(s,v,e): s.v=np.asarray(v); s.e=np.asarray(e)
    def E(s,vc): return np.interp(vc,s.v,s.e)
    def V(s,e): return np.interp(e,s.e,s.v)
def resample(r):
    t=r['t']; tg=np.arange(0,t[-1],DT)
    return tg,np.interp(tg,t,r['I']),np.interp(tg,t,r['V'])
def lp(I,tau):
    a=np.exp(-DT/tau); return lfilter([1-a],[1,-a],I)
def simulate(p,I,v_start,curve,iters=2):
    """open loop; p=[R0,R1,tau1,R2,tau2,wa,J0] (pack ohms, s, A^2 s)"""
    R0,R1,t1,R2,t2,wa,J0=p
    J=np.cumsum(I*I)*DT
    f=1+wa*np.exp(-J/max(J0,1.0))
    pol=R1*lp(f*I,t1)+(R2*lp(f*I,t2) if R2>0 else 0)
    E0=curve.E(v_start/NC)
    Vm=np.full_like(I,v_start)
    for _ in range(iters):
        e=E0-np.cumsum(Vm*I)*DT/3600
        ocv=NC*curve.V(e)
        Vm=ocv-f*R0*I-pol
    return Vm,ocv,f
TAUH=600.0
def simulate2(p,I,v_start,curve,H0=0.0,iters=2):
    """p=[R0,R1,tau1,wa,Hs,bias]: R scaled by f=1+wa*exp(-H/Hs), H=lowpass_TAUH(I^2)*TAUH-equivalent heat (A^2 s) incl. carry-over H0"""
    R0,R1,t1,wa,Hs,bias=p
    a=np.exp(-DT/TAUH)
    H=lfilter([DT],[1,-a],I*I,zi=[a*H0])[0]
    f=1+wa*np.exp(-H/max(Hs,1.0))
    pol=R1*lp(f*I,t1)
    E0=curve.E(v_start/NC); Vm=np.full_like(I,v_start)
    for _ in range(iters):
        e=E0-np.cumsum(Vm*I)*DT/3600
        ocv=NC*curve.V(e)
        Vm=ocv-bias-f*R0*I-pol
    return Vm,ocv,f,H
