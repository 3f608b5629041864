"""Reproducible fit + CV + one-time test scoring of the TB48D pack model (dronewatt battery module).
Run: python lab/scripts/battery/fit.py   -> prints a table, writes results.json and rust_ref.json into
BATTERY_OUT (default <tmp>/dronewatt-battery; see load.py), never into the repository."""
import json, numpy as np, time
from scipy.optimize import least_squares
from extract import flights, NC
from load import out
from ocvfit import KN, fit_robust, E_of
from ecm import Curve, resample, lp, simulate2, DT, TAUH
RATED_WH=129.96; RATED_AH=5.7
T0=time.time(); F=flights(); R={}
prev={r['next']:f for f,r in F.items() if r.get('next')}
med=lambda a: float(np.median(np.abs(a))) if len(a) else float('nan')
# ---------- 1. rest voltages + relaxation correction (train chain pairs only) ----------
pairs=[r for r in F.values() if not r['test'] and r.get('next') and not F[r['next']]['test']]
X=np.c_[[r['end_slope'] for r in pairs],np.ones(len(pairs))]; dv=np.array([F[r['next']]['v_start']-r['v_end_meas'] for r in pairs])
KREL=np.linalg.lstsq(X,dv,rcond=None)[0]
for r in F.values():
    if np.isfinite(r.get('v_end_meas',np.nan)): r['v_end_rest']=r['v_end_meas']+KREL[0]*r['end_slope']+KREL[1]
R['relax']=dict(k_s=float(KREL[0]),c_v=float(KREL[1]),n_pairs=len(pairs),resid_std_v=float(np.std(dv-X@KREL)),raw_std_v=float(np.std(dv)))
tp=[r for r in F.values() if r['test'] and r.get('next')]
R['relax']['test_pairs_abs_err_v']=[float(F[r['next']]['v_start']-r['v_end_rest']) for r in tp]
def rest_ok(r): return r.get('has_on') and np.isfinite(r.get('v_start',np.nan)) and np.isfinite(r.get('v_end_rest',np.nan))
# ---------- 2. OCV curve: E(v_cell) monotone piecewise linear, NNLS + Huber ----------
TAIL_FRAC=0.12  # energy share below 3.70 V/cell: NOT identified by data; from the generic LiPo table (SoC(3.70)~12%)
def curve_from(s):
    s=s.copy(); j=np.searchsorted(KN,3.70)   # segments below 3.70 V: prior shape
    above=np.sum(s[j:]*np.diff(KN)[j:]); tail=above*TAIL_FRAC/(1-TAIL_FRAC)
    shape=np.array([0.25,0.6,1.0,1.4])[:j]  # rising slope toward 3.70 (LiPo knee)
    s[:j]=shape/np.sum(shape*np.diff(KN)[:j])*tail
    return Curve(KN,np.concatenate([[0],np.cumsum(s*np.diff(KN))]))
def fit_curve(rs,lam=3.0):
    vs=np.array([r['v_start'] for r in rs])/NC; ve=np.array([r['v_end_rest'] for r in rs])/NC; E=np.array([r['E_wh'] for r in rs])
    return curve_from(fit_robust(vs,ve,E,lam))
def score_curve(c,rs):
    vs=np.array([r['v_start'] for r in rs])/NC; ve=np.array([r['v_end_rest'] for r in rs])/NC; E=np.array([r['E_wh'] for r in rs])
    eerr=c.E(vs)-c.E(ve)-E; vpred=NC*c.V(c.E(vs)-E); verr=vpred-NC*ve
    return eerr,verr
tr_rest=[r for r in F.values() if not r['test'] and rest_ok(r)]; te_rest=[r for r in F.values() if r['test'] and rest_ok(r)]
fold=lambda r: r['flight']%5
cv={}
for lam in [1.0,3.0,10.0,30.0]:
    ee=[];vv=[]
    for k in range(5):
        c=fit_curve([r for r in tr_rest if fold(r)!=k],lam); e,v=score_curve(c,[r for r in tr_rest if fold(r)==k]); ee+=list(e); vv+=list(v)
    cv[lam]=(med(ee),med(vv))
LAM=min(cv,key=lambda l: cv[l][0]); CURVE=fit_curve(tr_rest,LAM)
R['ocv']=dict(cv={str(k):dict(energy_mae_wh=v[0],end_v_mae_v=v[1]) for k,v in cv.items()},lam=LAM,knots_v=KN.tolist(),energy_wh=CURVE.e.tolist(),
              total_wh=float(CURVE.e[-1]),n_train=len(tr_rest))
# PX4 linear rules on rest voltages (energy between two rest voltages)
def px4_soc(vc,lo=3.6,hi=4.05): return np.clip((vc-lo)/(hi-lo),0,1)
def baseline_energy(rs,lo):
    return np.array([(px4_soc(r['v_start']/NC,lo)-px4_soc(r['v_end_rest']/NC,lo))*RATED_WH-r['E_wh'] for r in rs])
R['ocv']['train_px4_36_energy_mae']=med(baseline_energy(tr_rest,3.6)); R['ocv']['train_px4_35_energy_mae']=med(baseline_energy(tr_rest,3.5))
print('OCV CV (lam: energy MAE Wh, end-V MAE V):',{k:tuple(round(x,3) for x in v) for k,v in cv.items()},'chosen',LAM,'%.0fs'%(time.time()-T0))
# ---------- 3. equivalent circuit (open loop), CV over structures ----------
ecm_fl=[r for r in F.values() if r.get('has_on') and np.isfinite(r.get('v_start',np.nan)) and r['route'] not in ('A1','A2','A3','H')]
for r in ecm_fl:
    r['tg'],r['Ig'],r['Vg']=resample(r); r['m']=r['Ig']>3
def heat_carry(r,p,curve,cache):
    """heat (A^2 s) carried from the previous flight on the same pack (chain from parameters.csv times)"""
    pf=prev.get(r['flight'])
    if pf is None or 'Ig' not in F[pf] or not p[3]: return 0.0
    key=(pf,tuple(p))
    if key not in cache:
        q=F[pf]; H0=heat_carry(q,p,curve,cache); _,_,_,H=simulate2(p,q['Ig'],q['v_start'],curve,H0)
        gap=(r['tmin']-q['tmin'])*60-q['tg'][-1]; cache[key]=H[-1]*np.exp(-max(gap,0)/TAUH)
    return cache[key]
STRUCT={'R0':([0.07,0,10,0,1e5,0],[0,5]),'1RC':([0.05,0.02,5,0,1e5,0],[0,1,2,5]),'1RC+heat':([0.04,0.02,20,1.0,6e4,0],[0,1,2,3,4,5])}
LO=np.array([0,0,0.5,0,1e3,-1]); HI=np.array([1,1,120,5,1e7,1]); SC=np.array([0.01,0.01,2,0.5,3e4,0.05])
def fit_ecm(rs,curve,name):
    p0,free=STRUCT[name]; p0=np.array(p0,float); cache={}
    def res(x):
        p=p0.copy(); p[free]=x; cache.clear()
        return np.concatenate([(simulate2(p,r['Ig'],r['v_start'],curve,heat_carry(r,p,curve,cache))[0]-r['Vg'])[r['m']][::5] for r in rs])
    s=least_squares(res,p0[free],bounds=(LO[free],HI[free]),x_scale=SC[free],max_nfev=40); p=p0.copy(); p[free]=s.x; return p
def ecm_rmse(p,rs,curve):
    cache={}; return np.array([np.sqrt(np.mean(((simulate2(p,r['Ig'],r['v_start'],curve,heat_carry(r,p,curve,cache))[0]-r['Vg'])[r['m']])**2)) for r in rs])
tr_e=[r for r in ecm_fl if not r['test']]; te_e=[r for r in ecm_fl if r['test']]
R['ecm']={'cv':{}}
for name in STRUCT:
    errs=[]
    for k in range(5):
        rs=[r for r in tr_e if fold(r)!=k]; c=fit_curve([r for r in tr_rest if fold(r)!=k],LAM)
        p=fit_ecm(rs,c,name); errs+=list(ecm_rmse(p,[r for r in tr_e if fold(r)==k],c))
    R['ecm']['cv'][name]=float(np.median(errs)); print('ECM CV',name,'median RMSE %.3f V'%np.median(errs),'%.0fs'%(time.time()-T0))
BEST=min(R['ecm']['cv'],key=R['ecm']['cv'].get)
P=fit_ecm(tr_e,CURVE,BEST); R['ecm']['chosen']=BEST
R['ecm']['params']=dict(zip(['r0_ohm','r1_ohm','tau1_s','warm_a','heat_scale_a2s','bias_v'],map(float,P)),tau_heat_s=TAUH)
R['ecm']['train_median_rmse']=float(np.median(ecm_rmse(P,tr_e,CURVE)))
print('ECM params',np.round(P,5))
# ---------- 4. reference loops (mirrored 1:1 by src/battery/{circuit,forecast}.rs) ----------
def vcell(c,e): return float(np.interp(e,c.e,c.v))
class Est:
    def __init__(s,p,c,v_rest,H0=0.0,lam=0.999):
        s.p=p; s.c=c; s.E=float(c.E(v_rest/NC)); s.x1=0.0; s.H=H0; s.lam=lam
        s.th=np.array([p[0],p[1],p[5]]); s.P=np.diag([1e-4,1e-4,1e-2])
    def f(s): return 1+s.p[3]*np.exp(-s.H/s.p[4])
    def prop(s,dt,I,V=None):
        s.H=s.H*np.exp(-dt/TAUH)+I*I*TAUH*(1-np.exp(-dt/TAUH)); f=s.f(); e1=np.exp(-dt/s.p[2])
        s.x1=s.x1*e1+f*I*(1-e1); phi=np.array([f*I,s.x1,1.0])
        if V is None: V=NC*vcell(s.c,s.E)-s.th@phi   # open loop: model voltage drives the energy count
        s.E=max(s.E-V*I*dt/3600,0.0); ocv=NC*vcell(s.c,s.E); return phi,ocv
    def update(s,dt,I,V):
        if not(np.isfinite(dt) and np.isfinite(I) and np.isfinite(V)) or dt<=0 or dt>5 or V<=0 or I<-2: return None
        I=max(I,0.0); phi,ocv=s.prop(dt,I,V); vhat=ocv-s.th@phi; err=V-vhat
        if I>1.0:
            Pp=s.P@phi; g=Pp/(s.lam+phi@Pp); s.th=s.th+g*(-err); s.P=(s.P-np.outer(g,Pp))/s.lam
            s.th=np.clip(s.th,[0,0,-1],[0.5,0.5,1]); tr=np.trace(s.P)
            if tr>1.0: s.P*=1.0/tr
        return vhat,err
    def copy(s):
        n=Est.__new__(Est); n.__dict__=dict(s.__dict__); n.th=s.th.copy(); n.P=s.P.copy(); return n
def forecast(s,prof,thr=()):
    """prof: list of (dt_s, power_w). returns (vmin, t_vmin, v_end, crossings)"""
    s=s.copy(); t=0.0; vmin=np.inf; tmin=np.nan; vend=np.nan; cross=[np.nan]*len(thr)
    R0,R1,b=s.th
    for dt,P in prof:
        if not(np.isfinite(dt) and np.isfinite(P)) or dt<=0: continue
        P=max(P,0.0)
        s.H=s.H*np.exp(-dt/TAUH); f=s.f(); e1=np.exp(-dt/s.p[2])
        ocv=NC*vcell(s.c,s.E); C=ocv-b-R1*s.x1*e1; Re=f*R0+R1*f*(1-e1)
        disc=C*C-4*Re*P; I=(C-np.sqrt(disc))/(2*Re) if disc>=0 else C/(2*Re)
        V=C-Re*I; s.H+=I*I*TAUH*(1-np.exp(-dt/TAUH)); s.x1=s.x1*e1+f*I*(1-e1); s.E=max(s.E-V*I*dt/3600,0.0); t+=dt
        if V<vmin: vmin,tmin=V,t
        vend=V
        for j,th in enumerate(thr):
            if np.isnan(cross[j]) and V<th: cross[j]=t
    return vmin,tmin,vend,cross
# ---------- 5. online estimator: forgetting factor by CV-free choice on training flights ----------
def run_est(r,lam,ahead=True):
    cache={}; H0=heat_carry(r,P,CURVE,cache); s=Est(P,CURVE,r['v_start'],H0,lam)
    t,I,V=r['t'],r['I'],r['V']; e1=[];e10=[];states={}
    tmid=0.5*(t[r['i_on']]+t[r['i_off']])
    for k in range(1,len(t)):
        if t[k]>=tmid and 'mid' not in states: states['mid']=(s.copy(),k)
        o=s.update(t[k]-t[k-1],I[k],V[k])
        if o and I[k]>3: e1.append(o[1])
        if ahead and I[k]>3 and k%25==0:
            j=np.searchsorted(t,t[k]+10.0)
            if j<len(t) and I[j]>3:
                q=s.copy()
                for m in range(k+1,j+1): phi,ocv=q.prop(t[m]-t[m-1],max(I[m],0))
                e10.append(V[j]-(ocv-q.th@phi))
    return np.array(e1),np.array(e10),states
R['estimator']={}
for lam in [0.995,0.999,0.9995]:
    a=[];b=[]
    for r in tr_e[::3]:
        e1,e10,_=run_est(r,lam); a.append(np.sqrt(np.mean(e1**2))); b.append(np.sqrt(np.mean(e10**2)) if len(e10) else np.nan)
    R['estimator'][str(lam)]=dict(train_onestep_rmse=float(np.median(a)),train_10s_rmse=float(np.nanmedian(b)))
    print('estimator lam',lam,R['estimator'][str(lam)],'%.0fs'%(time.time()-T0))
LAMBDA=float(min(R['estimator'],key=lambda k:R['estimator'][k]['train_10s_rmse'])); R['estimator']['chosen']=LAMBDA
# ---------- 6. forecasts + baselines, on a set of flights ----------
THR=NC*3.5
def ma(x,n): return np.convolve(x,np.ones(n)/n,mode='same')
def evaluate(rs,rest_rs):
    out={}
    e,v=score_curve(CURVE,rest_rs); out['ocv_energy_mae_wh']=med(e); out['ocv_end_v_mae_v']=med(v)
    out['px4_36_energy_mae_wh']=med(baseline_energy(rest_rs,3.6)); out['px4_35_energy_mae_wh']=med(baseline_energy(rest_rs,3.5))
    out['full_pack_start_energy_err_wh']=med([RATED_WH-CURVE.E(r['v_start']/NC) for r in rest_rs])  # vs our curve (model-based truth)
    out['px4_start_energy_err_wh']=med([px4_soc(r['v_start']/NC)*RATED_WH-CURVE.E(r['v_start']/NC) for r in rest_rs])
    out['ardupilot_start_mah_err']=med([(1-CURVE.E(r['v_start']/NC)/CURVE.e[-1])*RATED_AH*1000 for r in rest_rs])
    out['ecm_median_rmse_v']=float(np.median(ecm_rmse(P,rs,CURVE)))
    pre=[];pre5=[];mid=[];c35=[];c35m=[];o1=[];o10=[];rest_end_ours=[];rest_end_px4=[];rest_end_ap=[]
    for r in rs:
        cache={}; H0=heat_carry(r,P,CURVE,cache)
        Pw=r['Vg']*r['Ig']; prof=list(zip(np.full(len(Pw),DT),Pw)); meas_min=r['Vg'][r['m']].min() if r['m'].any() else np.nan
        s0=Est(P,CURVE,r['v_start'],H0,LAMBDA)
        vmin,_,_,cr=forecast(s0,prof,[THR]); pre.append(vmin-meas_min)
        vmin5,_,_,_=forecast(s0,list(zip(np.full(len(Pw),DT),ma(Pw,50))),[THR]); pre5.append(vmin5-meas_min)
        below=np.where(r['m']&(r['Vg']<THR))[0]
        if len(below): c35.append(cr[0]-r['tg'][below[0]])
        e1,e10,st=run_est(r,LAMBDA); o1.append(np.sqrt(np.mean(e1**2))); o10.append(np.sqrt(np.mean(e10**2)) if len(e10) else np.nan)
        sm,k=st['mid']; tk=r['t'][k-1]; j=np.searchsorted(r['tg'],tk)
        vm,_,_,crm=forecast(sm,prof[j:],[THR]); rest_m=r['Vg'][j:][r['m'][j:]]
        if len(rest_m): mid.append(vm-rest_m.min())
        if len(below) and below[0]>=j: c35m.append(crm[0]+tk-r['tg'][below[0]])
        # resting voltage read under load at the last in-flight sample vs the relaxed end rest
        if np.isfinite(r.get('v_end_rest',np.nan)):
            t,I,V=r['t'],r['I'],r['V']; io=r['i_off']; s=Est(P,CURVE,r['v_start'],H0,LAMBDA)
            for kk in range(1,io+1): s.update(t[kk]-t[kk-1],I[kk],V[kk])
            rest_end_ours.append(NC*vcell(CURVE,s.E)-r['v_end_rest'])
            # PX4: cell V + 5 mOhm/cell * I, low-passed tau=1 s
            vf=V[0]/NC
            for kk in range(1,io+1): a=1-np.exp(-(t[kk]-t[kk-1])/1.0); vf+=a*(V[kk]/NC+0.005*I[kk]-vf)
            rest_end_px4.append(NC*vf-r['v_end_rest'])
            # ArduPilot: R=(Vref-V)/(I-Iref) low-passed (tau 10 s), resting=V+I*R
            i0=r['i_on']; vr,ir=V[max(i0-1,0)],I[max(i0-1,0)]; Rap=0.0
            for kk in range(i0,io+1):
                if I[kk]-ir>5: a=1-np.exp(-(t[kk]-t[kk-1])/10.0); Rap+=a*((vr-V[kk])/(I[kk]-ir)-Rap)
            rest_end_ap.append(V[io]+I[io]*Rap-r['v_end_rest'])
    out.update(preflight_min_v_mae=med(pre),preflight_ma5_min_v_mae=med(pre5),halftime_min_v_mae=med(mid),
               cross35_preflight_mae_s=med(c35),cross35_halftime_mae_s=med(c35m),n_cross=len(c35),
               online_onestep_rmse_v=float(np.median(o1)),online_10s_rmse_v=float(np.nanmedian(o10)),
               rest_under_load_ours_mae_v=med(rest_end_ours),rest_under_load_px4_mae_v=med(rest_end_px4),rest_under_load_ardupilot_mae_v=med(rest_end_ap),
               n_flights=len(rs),n_rest=len(rest_rs))
    return out
R['train']=evaluate(tr_e,tr_rest); print('train',json.dumps(R['train'],indent=0),'%.0fs'%(time.time()-T0))
R['test']=evaluate(te_e,te_rest); R['test_flights']=sorted(r['flight'] for r in te_e)
TARGET=dict(ocv_energy_mae_wh=1.0,ocv_end_v_mae_v=0.05,ecm_median_rmse_v=0.20,preflight_min_v_mae=0.30,halftime_min_v_mae=0.15)
print('\n%-34s %10s %10s %10s %8s'%('metric','train(in-sample/CV*)','test','target','ok'))
for k,v in R['test'].items():
    tg=TARGET.get(k); print('%-34s %10.3f %10.3f %10s %8s'%(k,R['train'][k],v,'' if tg is None else tg,'' if tg is None else ('yes' if v<=tg else 'MISSED')))
print('CV (train, 5 folds by flight): OCV energy %.3f Wh, end V %.3f V; ECM %s'%(cv[LAM][0],cv[LAM][1],R['ecm']['cv']))
# ---------- 7. reference numbers for the Rust port ----------
s=Est(P,CURVE,24.0,0.0,LAMBDA); trace=[]
for k in range(50):
    I=20.0 if k<30 else 5.0; o=s.update(0.2,I,23.0-0.05*I); trace.append(o[0])
s2=Est(P,CURVE,24.0,0.0,LAMBDA); fc=forecast(s2,[(0.5,500.0)]*120+[(0.5,100.0)]*20,[22.5,21.0])
json.dump(dict(curve_v=CURVE.v.tolist(),curve_e=CURVE.e.tolist(),params=P.tolist(),tau_heat=TAUH,lam=LAMBDA,
  est_vhat=trace,est_theta=s.th.tolist(),est_energy=s.E,fc=[fc[0],fc[1],fc[2]]+list(fc[3])),open(out('rust_ref.json'),'w'),indent=1)
json.dump(R,open(out('results.json'),'w'),indent=1,default=float)
